// Checks that a failing write (full disk, I/O error) in any format, and in `numerics`, is reported, leaves no
// temporary and never replaces the file that was there; failures are injected into the one file writer.
#include <gtest/gtest.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <vector>

#include "app/numerics.hpp"
#include "base/atomic_file.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

// Makes a step of the file writer fail for the life of the guard.
class InjectedFileFailure {
 public:
  InjectedFileFailure(FileStep step, int error, std::uint64_t after_bytes = 0) { inject_file_failure(step, error, after_bytes); }
  ~InjectedFileFailure() { inject_file_failure(FileStep::kNone, 0); }
  InjectedFileFailure(const InjectedFileFailure&) = delete;
  InjectedFileFailure& operator=(const InjectedFileFailure&) = delete;
};

// Noise, which does not compress: every format writes about as many bytes as the image has values.
LinearImage noise_image(u32 width, u32 height) {
  LinearImage image;
  image.width = width;
  image.height = height;
  u32 state = 2024;
  for (u32 i = 0; i < width * height * 3; ++i) {
    state = state * 1664525u + 1013904223u;
    image.rgb.push_back(static_cast<float>(state >> 8) * 0x1p-24f);
  }
  return image;
}

struct FailureCase {
  FileStep step;
  std::uint64_t after_bytes;
  const char* name;
};

// Every step of the writer, a write failing at the first byte and in the middle of the data.
const std::vector<FailureCase> kFailures = {
    {FileStep::kCreate, 0, "create"}, {FileStep::kWrite, 0, "first write"}, {FileStep::kWrite, 5000, "write mid-file"},
    {FileStep::kSync, 0, "fsync"},    {FileStep::kClose, 0, "close"},       {FileStep::kRename, 0, "rename"}};

TEST(CheckedImageWrites, FailureInAnyStepOfAnyFormatKeepsTheOldFileAndLeavesNoTemporary) {
  const LinearImage image = noise_image(200, 150);  // every format writes well past 5000 bytes
  for (const char* name : {"image.png", "image.pfm", "image.exr"}) {
    for (const FailureCase& failure : kFailures) {
      for (const int error : {ENOSPC, EIO}) {
        SCOPED_TRACE(std::string(name) + ", " + failure.name + ", " + std::strerror(error));
        test::TempDir dir;
        test::write_text_file(dir / name, "the previous image\n");
        try {
          InjectedFileFailure injected(failure.step, error, failure.after_bytes);
          write_image(dir / name, image);
          ADD_FAILURE() << "no error";
        } catch (const InputError& e) {
          // One line naming the file and the operating system's reason, whatever wrapped it on the way (OpenEXR).
          const std::string message = e.what();
          EXPECT_EQ(message.rfind((dir / name).string() + ": cannot write the image: ", 0), 0u) << message;
          EXPECT_NE(message.find(std::strerror(error)), std::string::npos) << message;
          EXPECT_EQ(message.find('\n'), std::string::npos) << message;
        }
        EXPECT_EQ(dir.entries(), std::vector<std::string>{name});
        EXPECT_TRUE(test::read_text_file(dir / name) == "the previous image\n") << "the file was replaced";
      }
    }
  }
}

TEST(CheckedImageWrites, WritesSucceedOnceTheFailureIsGone) {
  test::TempDir dir;
  const LinearImage image = noise_image(20, 10);
  {
    InjectedFileFailure injected(FileStep::kSync, ENOSPC);
    EXPECT_THROW(write_image(dir / "image.pfm", image), InputError);
  }
  write_image(dir / "image.pfm", image);
  EXPECT_EQ(test::read_pfm(dir / "image.pfm").rgb, image.rgb);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"image.pfm"});
}

TEST(AtomicFiles, PublishedReplacesUnpublishedVanishes) {
  test::TempDir dir;
  test::write_text_file(dir / "a.txt", "old\n");
  {
    AtomicFile file(dir / "a.txt", "the text");
    file.write("new\n");
    file.finish();
    EXPECT_EQ(dir.entries().size(), 2u);  // the temporary, beside the target
    EXPECT_EQ(test::read_text_file(dir / "a.txt"), "old\n");
  }  // never published
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"a.txt"});
  EXPECT_EQ(test::read_text_file(dir / "a.txt"), "old\n");
  write_file_unpublished(dir / "a.txt", "the text", "new\n").publish();
  EXPECT_EQ(test::read_text_file(dir / "a.txt"), "new\n");
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"a.txt"});
}

// ---- numerics: the table, the plot and the images, all or nothing ----

NumericsOptions small_numerics(const std::filesystem::path& folder) {
  NumericsOptions options;
  options.scene = test::scene_path("tiny.json").string();
  options.output_folder = folder.string();
  options.width = 24;
  options.height = 16;
  options.spp = 1;
  options.depth = 3;
  options.threads = 2;
  options.formats = {"float", "double", "q16.16"};
  return options;
}

const std::vector<std::string> kNumericsFiles = {"double.png", "error-vs-bits.svg", "float.png", "numerics.csv", "q16.16.png", "side-by-side.png"};

TEST(CheckedNumericsWrites, WritesEveryFile) {
  test::TempDir dir;
  EXPECT_EQ(run_numerics(small_numerics(dir / "out")), 0);
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir / "out")) names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, kNumericsFiles);
  EXPECT_GT(std::filesystem::file_size(dir / "out" / "numerics.csv"), 100u);
  EXPECT_GT(std::filesystem::file_size(dir / "out" / "error-vs-bits.svg"), 1000u);
}

// A failure in any file, early or late, and in any step: an error naming a file of the folder, and the folder as
// it was (an old table kept, nothing added), or no folder at all where there was none.
TEST(CheckedNumericsWrites, AnyFailureLeavesTheFolderAsItWas) {
  for (const FailureCase& failure : {FailureCase{FileStep::kWrite, 0, "first write"}, FailureCase{FileStep::kWrite, 3000, "a later file"},
                                     FailureCase{FileStep::kSync, 0, "fsync"}, FailureCase{FileStep::kRename, 0, "rename"}}) {
    for (const bool folder_exists : {true, false}) {
      SCOPED_TRACE(std::string(failure.name) + (folder_exists ? ", existing folder" : ", new folder"));
      test::TempDir dir;
      const std::filesystem::path out = dir / "out";
      if (folder_exists) {
        std::filesystem::create_directory(out);
        test::write_text_file(out / "numerics.csv", "the previous table\n");
      }
      try {
        InjectedFileFailure injected(failure.step, ENOSPC, failure.after_bytes);
        run_numerics(small_numerics(out));
        ADD_FAILURE() << "no error";
      } catch (const InputError& e) {
        const std::string message = e.what();
        EXPECT_EQ(message.rfind(out.string() + "/", 0), 0u) << message;
        EXPECT_NE(message.find(": cannot write "), std::string::npos) << message;
        EXPECT_NE(message.find(std::strerror(ENOSPC)), std::string::npos) << message;
      }
      if (folder_exists) {
        std::vector<std::string> names;
        for (const auto& entry : std::filesystem::directory_iterator(out)) names.push_back(entry.path().filename().string());
        EXPECT_EQ(names, std::vector<std::string>{"numerics.csv"});
        EXPECT_TRUE(test::read_text_file(out / "numerics.csv") == "the previous table\n") << "the table was replaced";
      } else {
        EXPECT_FALSE(std::filesystem::exists(out));
      }
    }
  }
}

}  // namespace
}  // namespace pt

namespace pt {
namespace {

// Outputs never overwrite inputs: the image, the checkpoint, the scene and every file it reads are different files,
// compared by device and inode. Once `--checkpoint scene.json` replaced the scene with a film and exited 0, and
// `--checkpoint out.pfm -o out.pfm` left an image where the film was to be.
TEST(OutputsAndInputs, AnOutputThatIsAnInputIsRefusedBeforeRendering) {
  test::TempDir dir;
  LinearImage sky;
  sky.width = 4, sky.height = 2;
  sky.rgb.assign(24, 0.5f);
  write_image(dir / "sky.png", sky);
  const std::string sky_bytes = test::read_text_file(dir / "sky.png");
  const std::string scene_text = R"({"camera": {"look_from": [0, 0, 1], "look_at": [0, 0, 0], "vertical_fov": 40},
    "render": {"width": 8, "height": 8, "samples_per_pixel": 2}, "background": {"type": "environment", "file": "sky.png"},
    "objects": [{"type": "sphere", "center": [0, 0, -1], "radius": 0.5, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}]})";
  test::write_text_file(dir / "scene.json", scene_text);
  std::filesystem::create_hard_link(dir / "sky.png", dir / "same-sky.png");
  const std::string scene = test::quoted(dir / "scene.json") + " ";
  const auto refused = [&](const std::string& arguments, const std::string& expected) {
    const test::CommandResult result = test::run_pathtracer("render " + scene + arguments, dir);
    EXPECT_EQ(result.exit_code, 1) << arguments << "\n" << result.err;
    EXPECT_NE(result.err.find(expected), std::string::npos) << arguments << "\n" << result.err;
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  };
  refused("--checkpoint " + test::quoted(dir / "scene.json") + " -o " + test::quoted(dir / "out.png"),
          (dir / "scene.json").string() + ": cannot write the checkpoint there: it is '" + (dir / "scene.json").string() + "', which this render reads");
  refused("-o " + test::quoted(dir / "same-sky.png"), "cannot write the image there: it is '" + (dir / "sky.png").string() + "', which this render reads");
  refused("--checkpoint " + test::quoted(dir / "out.pfm") + " -o " + test::quoted(dir / "." / "out.pfm"), "cannot write the image and the checkpoint to one file");
  EXPECT_EQ(test::read_text_file(dir / "scene.json"), scene_text);
  EXPECT_EQ(test::read_text_file(dir / "sky.png"), sky_bytes);
  EXPECT_FALSE(std::filesystem::exists(dir / "out.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "out.pfm"));
  // A resumed film saved again where it was read is the usual way to go on: allowed.
  const std::string film = test::quoted(dir / "film.pfm");
  ASSERT_EQ(test::run_pathtracer("render " + scene + "--checkpoint " + film + " -o " + test::quoted(dir / "a.pfm"), dir).exit_code, 0);
  const test::CommandResult resumed =
      test::run_pathtracer("render " + scene + "--spp 4 --resume " + film + " --checkpoint " + film + " -o " + test::quoted(dir / "b.pfm"), dir);
  EXPECT_EQ(resumed.exit_code, 0) << resumed.err;
  // The image onto the film resumed is refused.
  refused("--spp 6 --resume " + film + " -o " + film, "which this render reads");
}

// An image written to a symbolic link lands in the file the link points to; the link stays (once it was replaced by
// the image), whether its file exists yet or not, and through a chain of links.
TEST(OutputsAndInputs, ImageWrittenThroughASymbolicLinkKeepsTheLink) {
  test::TempDir dir;
  std::filesystem::create_directory(dir / "elsewhere");
  std::filesystem::create_symlink("elsewhere/new.pfm", dir / "link.pfm");
  std::filesystem::create_symlink("link.pfm", dir / "link-to-link.pfm");
  const std::string scene = test::quoted(test::scene_path("tiny.json"));
  for (const char* name : {"link.pfm", "link-to-link.pfm"}) {
    const test::CommandResult result = test::run_pathtracer("render " + scene + " --width 8 --height 6 --spp 1 -q -o " + test::quoted(dir / name), dir);
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_TRUE(std::filesystem::is_symlink(dir / "link.pfm"));
    EXPECT_TRUE(std::filesystem::is_symlink(dir / "link-to-link.pfm"));
    EXPECT_EQ(test::read_pfm(dir / "elsewhere" / "new.pfm").width, 8u);
    std::filesystem::remove(dir / "elsewhere" / "new.pfm");
  }
}

}  // namespace
}  // namespace pt
