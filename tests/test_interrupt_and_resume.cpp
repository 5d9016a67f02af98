// Stopping a render early and going on later: interrupts, the time limit, saved films and resumed renders.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <initializer_list>
#include <thread>

#include <fmt/format.h>

#include "film/checkpoint.hpp"
#include "film/film.hpp"
#include "test_support.hpp"

extern char** environ;

namespace pt {
namespace {

// A film rendered to the end in one go, and the same film stopped after its first pass, saved, and resumed by a new
// backend: the sums are the same bit for bit, since every pixel's samples are added in order either way.
void expect_resume_is_bitwise_equal(Integrator integrator) {
  const FlatScene<float> scene = test::tiny_reference_scene<float>(9, 3);
  const auto whole_backend = make_cpu_backend<float>(2, integrator);
  const RenderedFilm whole = render_film(*whole_backend, scene);
  const std::vector<FilmPixel> whole_pixels(whole.pixels().begin(), whole.pixels().end());
  EXPECT_EQ(whole.samples_done, 9u);
  EXPECT_FALSE(whole.stopped_early);

  std::vector<FilmPixel> saved;
  u32 saved_samples = 0;
  int passes = 0;
  RenderControl stop_after_one_pass;
  stop_after_one_pass.stop_requested = [&] { return passes++ > 0; };
  stop_after_one_pass.checkpoint = [&](std::span<const FilmPixel> pixels, u32 samples) {
    saved.assign(pixels.begin(), pixels.end());
    saved_samples = samples;
  };
  const auto first_backend = make_cpu_backend<float>(2, integrator);
  const RenderedFilm part = render_film(*first_backend, scene, {}, stop_after_one_pass);
  EXPECT_TRUE(part.stopped_early);
  ASSERT_GT(part.samples_done, 0u);
  ASSERT_LT(part.samples_done, 9u);
  EXPECT_EQ(saved_samples, part.samples_done) << "a stopped render saves its film";
  EXPECT_EQ(part.stats.samples, static_cast<u64>(saved.size()) * part.samples_done);

  RenderControl resume;
  resume.start_film = saved;
  resume.start_samples = saved_samples;
  const auto second_backend = make_cpu_backend<float>(2, integrator);
  const RenderedFilm rest = render_film(*second_backend, scene, {}, resume);
  EXPECT_EQ(rest.samples_done, 9u);
  EXPECT_TRUE(test::same_film(std::vector<FilmPixel>(rest.pixels().begin(), rest.pixels().end()), whole_pixels));
}

TEST(ResumedRender, MegakernelFilmIsBitwiseEqualToAnUninterruptedOne) { expect_resume_is_bitwise_equal(Integrator::kMegakernel); }
TEST(ResumedRender, WavefrontFilmIsBitwiseEqualToAnUninterruptedOne) { expect_resume_is_bitwise_equal(Integrator::kWavefront); }
// Bidirectional path tracing folds each sample's splats into the film before the next sample, so a film saved between
// passes holds whole samples and resumes as well.
TEST(ResumedRender, BidirectionalFilmIsBitwiseEqualToAnUninterruptedOne) { expect_resume_is_bitwise_equal(Integrator::kBidirectional); }

TEST(ResumedRender, TimeLimitStopsEarly) {
  const FlatScene<float> scene = test::tiny_reference_scene<float>(1000000, 3);
  RenderControl control;
  control.time_limit_seconds = 0.2;
  const auto backend = make_cpu_backend<float>(2, Integrator::kMegakernel);
  const auto start = std::chrono::steady_clock::now();
  const RenderedFilm film = render_film(*backend, scene, {}, control);
  EXPECT_TRUE(film.stopped_early);
  EXPECT_LT(film.samples_done, 1000000u);
  // Generous: the point is that a million samples per pixel were not all rendered (minutes).
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 30.0);
}

// The key of a scene file read a piece at a time is that of its whole text, for a file of several pieces (so that
// checkpoints written before the file was read in pieces still resume), and a file that cannot be read counts as empty.
TEST(Checkpoint, KeyOfTheFileIsTheKeyOfItsText) {
  test::TempDir dir;
  std::string text;
  for (int i = 0; text.size() < 2600000; ++i) text += "{\"type\": \"sphere\", \"center\": [" + std::to_string(i) + ", 0, 0]},\n";
  {
    std::ofstream out(dir / "scene.json", std::ios::binary);
    out << text;
  }
  EXPECT_EQ(checkpoint_key_of_file(dir / "scene.json", "depth 5 seed 1", 3, 2), checkpoint_key(text, "depth 5 seed 1", 3, 2));
  EXPECT_NE(checkpoint_key_of_file(dir / "scene.json", "depth 5 seed 1", 3, 2), checkpoint_key(text + " ", "depth 5 seed 1", 3, 2));
  EXPECT_EQ(checkpoint_key_of_file(dir / "missing.json", "depth 5 seed 1", 3, 2), checkpoint_key("", "depth 5 seed 1", 3, 2));
}

TEST(Checkpoint, RoundTripsAndRefusesAnotherSceneSizeOrSettings) {
  test::TempDir dir;
  const CheckpointKey key = checkpoint_key("{\"scene\": 1}", "depth 5 seed 1", 3, 2);
  std::vector<FilmPixel> film(6);
  for (std::size_t i = 0; i < film.size(); ++i) film[i] = FilmPixel{0.1 * i, 0.2, 0.3, 0.05f, static_cast<u32>(i), 7, i % 2 ? 16u : 0u};
  write_checkpoint(dir / "a.film", key, film, 5);
  const Checkpoint back = read_checkpoint(dir / "a.film", key);
  EXPECT_EQ(back.samples_done, 5u);
  EXPECT_TRUE(test::same_film(back.film, film));

  const auto refused = [&](const CheckpointKey& other, const std::string& expected) {
    try {
      read_checkpoint(dir / "a.film", other);
      ADD_FAILURE() << "accepted a checkpoint for another render";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("a.film"), std::string::npos) << message;
      EXPECT_NE(message.find(expected), std::string::npos) << message;
    }
  };
  refused(checkpoint_key("{\"scene\": 2}", "depth 5 seed 1", 3, 2), "another scene");
  refused(checkpoint_key("{\"scene\": 1}", "depth 5 seed 2", 3, 2), "other settings");
  refused(checkpoint_key("{\"scene\": 1}", "depth 5 seed 1", 2, 3), "2x3");
}

TEST(Checkpoint, CutShortOrForeignFileIsRefused) {
  test::TempDir dir;
  const CheckpointKey key = checkpoint_key("scene", "settings", 4, 4);
  write_checkpoint(dir / "a.film", key, std::vector<FilmPixel>(16), 1);
  std::filesystem::resize_file(dir / "a.film", std::filesystem::file_size(dir / "a.film") - 1);
  EXPECT_THROW(read_checkpoint(dir / "a.film", key), InputError);
  test::write_text_file(dir / "b.film", "not a film at all, but long enough to hold a header");
  EXPECT_THROW(read_checkpoint(dir / "b.film", key), InputError);
  EXPECT_THROW(read_checkpoint(dir / "missing.film", key), InputError);
}

// A checkpoint of the version whose film kept the odd samples' brightness (same size, other meaning) is refused by
// name, not resumed into a misjudged adaptive render.
TEST(Checkpoint, OlderFilmLayoutIsRefusedByName) {
  test::TempDir dir;
  const CheckpointKey key = checkpoint_key("scene", "settings", 4, 4);
  write_checkpoint(dir / "a.film", key, std::vector<FilmPixel>(16), 1);
  std::string bytes = test::read_text_file(dir / "a.film");
  ASSERT_EQ(bytes.substr(0, 8), "PTFILM04");
  bytes[7] = '3';
  test::write_text_file(dir / "a.film", bytes);
  try {
    read_checkpoint(dir / "a.film", key);
    ADD_FAILURE() << "an older checkpoint was read";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("older version, whose adaptive sampling kept other sums"), std::string::npos) << error.what();
  }
}

// One flipped bit anywhere in a checkpoint, in its header, a pixel's sums or the checksum itself, is refused on one
// line naming the file; once such a film resumed into a wrong image with status 0.
TEST(Checkpoint, AnyFlippedBitIsRefused) {
  test::TempDir dir;
  const CheckpointKey key = checkpoint_key("scene", "settings", 3, 2);
  std::vector<FilmPixel> film(6);
  for (std::size_t i = 0; i < film.size(); ++i) film[i] = FilmPixel{0.25 * i, 0.5, 1.0 + i, 0.5f, static_cast<u32>(i), 3, 0};
  write_checkpoint(dir / "a.film", key, film, 3);
  const std::string whole = test::read_text_file(dir / "a.film");
  for (std::size_t byte = 0; byte < whole.size(); ++byte) {
    for (const int bit : {0, 5}) {
      std::string flipped = whole;
      flipped[byte] = static_cast<char>(flipped[byte] ^ (1 << bit));
      test::write_text_file(dir / "b.film", flipped);
      try {
        read_checkpoint(dir / "b.film", key);
        ADD_FAILURE() << "accepted with bit " << bit << " of byte " << byte << " flipped";
      } catch (const InputError& e) {
        const std::string message = e.what();
        EXPECT_EQ(message.rfind((dir / "b.film").string() + ": cannot resume: ", 0), 0u) << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
      }
    }
  }
  // The film's own bytes: the checksum is what finds them.
  std::string flipped = whole;
  flipped[whole.size() - 20] ^= 1;
  test::write_text_file(dir / "b.film", flipped);
  EXPECT_THROW(
      {
        try {
          read_checkpoint(dir / "b.film", key);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("its checksum does not match its content"), std::string::npos) << e.what();
          throw;
        }
      },
      InputError);
}

#ifdef PT_PATHTRACER_BINARY
// No temporary of the atomic writer (hidden files ending in .tmp plus an extension) left in the folder.
bool temporaries_left(const std::filesystem::path& folder) {
  for (const auto& entry : std::filesystem::directory_iterator(folder))
    if (entry.path().filename().string().find(".tmp") != std::string::npos) return true;
  return false;
}

TEST(ResumedRender, TimeLimitThenResumeGivesTheSameImageFile) {
  test::TempDir dir;
  const std::string scene = test::quoted(test::scene_path("book1-final.json"));
  const std::string size = " --width 48 --height 27 --spp 12 --threads 2 ";
  ASSERT_EQ(test::run_pathtracer("render " + scene + size + "-o " + test::quoted(dir / "whole.pfm"), dir).exit_code, 0);
  const test::CommandResult part = test::run_pathtracer(
      "render " + scene + size + "--time-limit 0.000001 --checkpoint " + test::quoted(dir / "film") + " -o " + test::quoted(dir / "part.pfm"), dir);
  ASSERT_EQ(part.exit_code, 0) << part.err;
  EXPECT_NE(part.err.find("stopped by the time limit after 1 of 12 samples per pixel"), std::string::npos) << part.err;
  const test::CommandResult rest =
      test::run_pathtracer("render " + scene + size + "--resume " + test::quoted(dir / "film") + " -o " + test::quoted(dir / "rest.pfm"), dir);
  ASSERT_EQ(rest.exit_code, 0) << rest.err;
  EXPECT_EQ(test::read_text_file(dir / "rest.pfm"), test::read_text_file(dir / "whole.pfm")) << "the resumed image differs";
  // Resumed with another seed: refused, one line naming the file, no image.
  const test::CommandResult other = test::run_pathtracer(
      "render " + scene + size + "--seed 99 --resume " + test::quoted(dir / "film") + " -o " + test::quoted(dir / "other.pfm"), dir);
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_NE(other.err.find("cannot resume"), std::string::npos) << other.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "other.pfm"));
  // Likewise with the other sampler: its samples would not continue the film's sequences.
  const test::CommandResult sampler = test::run_pathtracer(
      "render " + scene + size + "--sampler independent --resume " + test::quoted(dir / "film") + " -o " + test::quoted(dir / "other.pfm"), dir);
  EXPECT_EQ(sampler.exit_code, 1);
  EXPECT_NE(sampler.err.find("cannot resume"), std::string::npos) << sampler.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "other.pfm"));
  EXPECT_FALSE(temporaries_left(dir.path()));
}

TEST(ResumedRender, FinishedRenderResumedToMoreSamplesGivesTheSameImageFile) {
  test::TempDir dir;
  const std::string scene = test::quoted(test::scene_path("book1-final.json")) + " --width 48 --height 27 --threads 2 ";
  ASSERT_EQ(test::run_pathtracer("render " + scene + "--spp 12 -o " + test::quoted(dir / "whole.pfm"), dir).exit_code, 0);
  ASSERT_EQ(
      test::run_pathtracer("render " + scene + "--spp 5 --checkpoint " + test::quoted(dir / "film") + " -o " + test::quoted(dir / "five.pfm"), dir)
          .exit_code,
      0);
  const test::CommandResult more =
      test::run_pathtracer("render " + scene + "--spp 12 --resume " + test::quoted(dir / "film") + " -o " + test::quoted(dir / "more.pfm"), dir);
  ASSERT_EQ(more.exit_code, 0) << more.err;
  EXPECT_EQ(test::read_text_file(dir / "more.pfm"), test::read_text_file(dir / "whole.pfm"));
  // Fewer samples than the film holds cannot be had from it.
  EXPECT_EQ(test::run_pathtracer("render " + scene + "--spp 3 --resume " + test::quoted(dir / "film") + " -o " + test::quoted(dir / "x.pfm"), dir)
                .exit_code,
            1);
}

// Starts the program in the background on a render that would take hours; returns its process id.
pid_t start_long_render(const test::TempDir& dir, const std::string& extra) {
  const std::string command = "exec '" + test::pathtracer_binary() + "' render " + test::quoted(test::scene_path("book1-final.json")) +
                              " --width 64 --height 36 --spp 1000000 --threads 2 -o " + test::quoted(dir / "image.pfm") + extra + " 2> " +
                              test::quoted(dir / "stderr.txt");
  const char* argv[] = {"/bin/sh", "-c", command.c_str(), nullptr};
  pid_t pid = -1;
  EXPECT_EQ(posix_spawn(&pid, "/bin/sh", nullptr, nullptr, const_cast<char* const*>(argv), environ), 0);
  return pid;
}

// Waits for the first line the program prints (the render has begun), at most `seconds`.
void wait_for_start(const test::TempDir& dir, double seconds) {
  const auto start = std::chrono::steady_clock::now();
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < seconds) {
    if (std::filesystem::exists(dir / "stderr.txt") && std::filesystem::file_size(dir / "stderr.txt") > 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // into the passes
}

// The exit status of `pid`, waiting at most `seconds` (then killed: -1).
int exit_status_within(pid_t pid, double seconds) {
  const auto start = std::chrono::steady_clock::now();
  int status = 0;
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > seconds) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A long render started, its first passes waited for, then sent `signals` one after another: its exit status.
int exit_status_after(const test::TempDir& dir, const std::string& extra, std::initializer_list<int> signals) {
  const pid_t pid = start_long_render(dir, extra);
  wait_for_start(dir, 60);
  for (const int signal : signals) kill(pid, signal);
  return exit_status_within(pid, 60);
}

TEST(Interrupt, SigintWritesThePartialImageAndItsFilmAndExits130) {
  test::TempDir dir;
  EXPECT_EQ(exit_status_after(dir, " --checkpoint " + test::quoted(dir / "film"), {SIGINT}), 130);
  const std::string err = test::read_text_file(dir / "stderr.txt");
  EXPECT_NE(err.find("stopped by an interrupt (SIGINT) after"), std::string::npos) << err;
  const LinearImage image = test::read_pfm(dir / "image.pfm");
  EXPECT_EQ(image.width, 64u);
  EXPECT_EQ(image.height, 36u);
  EXPECT_TRUE(std::filesystem::exists(dir / "film"));
  EXPECT_FALSE(temporaries_left(dir.path()));
}

TEST(Interrupt, SigtermExits143) {
  test::TempDir dir;
  EXPECT_EQ(exit_status_after(dir, "", {SIGTERM}), 143);
  EXPECT_TRUE(std::filesystem::exists(dir / "image.pfm"));
  EXPECT_FALSE(temporaries_left(dir.path()));
}

// While the scene loads there is nothing to save: the first signal ends the program at once, with no image, where
// it once waited for the loading to end and the first pass to be rendered.
TEST(Interrupt, SignalWhileTheSceneLoadsEndsAtOnce) {
  test::TempDir dir;
  // A grid of 2 million triangles as a binary PLY: seconds to read and to build its BVH.
  constexpr u32 kSide = 1001;
  std::string ply = fmt::format(
      "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
      "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
      kSide * kSide, 2 * (kSide - 1) * (kSide - 1));
  const auto put = [&](const auto value) { ply.append(reinterpret_cast<const char*>(&value), sizeof value); };
  for (u32 y = 0; y < kSide; ++y)
    for (u32 x = 0; x < kSide; ++x) put(float(x) / kSide), put(float(y) / kSide), put(float((x * 7 + y * 13) % 5) / (5 * kSide));
  for (u32 y = 0; y + 1 < kSide; ++y)
    for (u32 x = 0; x + 1 < kSide; ++x) {
      const int corner = static_cast<int>(y * kSide + x), side = static_cast<int>(kSide);
      put(u8{3}), put(corner), put(corner + 1), put(corner + side);
      put(u8{3}), put(corner + 1), put(corner + side + 1), put(corner + side);
    }
  test::write_text_file(dir / "grid.ply", ply);
  test::write_text_file(dir / "scene.json", R"({"camera": {"look_from": [0.5, 0.5, 2], "look_at": [0.5, 0.5, 0], "vertical_fov": 40},
    "render": {"width": 16, "height": 16, "samples_per_pixel": 1}, "objects": [{"type": "mesh", "file": "grid.ply"}]})");
  const std::string command = "exec '" + test::pathtracer_binary() + "' render " + test::quoted(dir / "scene.json") + " --threads 2 -o " +
                              test::quoted(dir / "image.pfm") + " 2> " + test::quoted(dir / "stderr.txt");
  const char* argv[] = {"/bin/sh", "-c", command.c_str(), nullptr};
  pid_t pid = -1;
  ASSERT_EQ(posix_spawn(&pid, "/bin/sh", nullptr, nullptr, const_cast<char* const*>(argv), environ), 0);
  // Once the program catches SIGTERM (its handler is installed first thing; a sanitized process takes a while to get
  // there), while it reads the grid.
  const auto catches_sigterm = [&] {
    std::ifstream status("/proc/" + std::to_string(pid) + "/status");
    for (std::string line; std::getline(status, line);)
      if (line.starts_with("SigCgt:")) return ((std::stoull(line.substr(7), nullptr, 16) >> (SIGTERM - 1)) & 1) != 0;
    return false;
  };
  for (int i = 0; i < 3000 && !catches_sigterm(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_TRUE(catches_sigterm());
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  kill(pid, SIGTERM);
  const auto signalled = std::chrono::steady_clock::now();
  EXPECT_EQ(exit_status_within(pid, 60), 143);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count(), 1.0);
  EXPECT_FALSE(std::filesystem::exists(dir / "image.pfm"));
  EXPECT_EQ(test::read_text_file(dir / "stderr.txt"), "");
  EXPECT_FALSE(temporaries_left(dir.path()));
}

// A checkpoint that cannot be written (its folder gone, as a full disk would) does not cost the image: the render
// goes on, the image is written, and the status is 1 with a line naming the checkpoint. Once no image was written.
TEST(Checkpoint, FailedCheckpointStillWritesTheImage) {
  test::TempDir dir;
  std::filesystem::create_directory(dir / "saves");
  const pid_t pid = start_long_render(dir, " --time-limit 3 --checkpoint " + test::quoted(dir / "saves" / "film") + " --checkpoint-interval 0.1");
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  std::filesystem::remove_all(dir / "saves");
  EXPECT_EQ(exit_status_within(pid, 120), 1);
  const std::string err = test::read_text_file(dir / "stderr.txt");
  EXPECT_NE(err.find("warning: " + (dir / "saves" / "film").string() + ": cannot write the checkpoint"), std::string::npos) << err;
  EXPECT_NE(err.find("pathtracer: error: " + (dir / "saves" / "film").string() + ": cannot write the checkpoint"), std::string::npos) << err;
  EXPECT_NE(err.find("(the image was written to " + (dir / "image.pfm").string() + ")"), std::string::npos) << err;
  EXPECT_EQ(test::read_pfm(dir / "image.pfm").width, 64u);
  EXPECT_FALSE(temporaries_left(dir.path()));
}

// A signal that arrives while the finished image is being written: the write goes on and the image is whole, and the
// status still says that a signal came (it was 0, so a script could not tell), with a line saying the image is complete.
TEST(Interrupt, SignalDuringTheFinalWriteExits143WithTheImageWhole) {
  test::TempDir dir;
  const std::string command = "exec '" + test::pathtracer_binary() + "' render " + test::quoted(test::scene_path("tiny.json")) +
                              " --width 2048 --height 2048 --spp 1 --depth 1 --threads 2 -o " + test::quoted(dir / "image.png") + " 2> " +
                              test::quoted(dir / "stderr.txt");
  const char* argv[] = {"/bin/sh", "-c", command.c_str(), nullptr};
  pid_t pid = -1;
  ASSERT_EQ(posix_spawn(&pid, "/bin/sh", nullptr, nullptr, const_cast<char* const*>(argv), environ), 0);
  // The image's temporary appears when the render has finished and its encoding begins (a tenth of a second or more).
  bool writing = false;
  for (int i = 0; i < 120000 && !writing && waitpid(pid, nullptr, WNOHANG) == 0; ++i) {
    writing = temporaries_left(dir.path());
    if (!writing) std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  ASSERT_TRUE(writing) << "the write was not seen";
  kill(pid, SIGTERM);
  EXPECT_EQ(exit_status_within(pid, 60), 143);
  const std::string err = test::read_text_file(dir / "stderr.txt");
  EXPECT_NE(err.find("SIGTERM arrived after the render had finished: the image of all 1 samples per pixel is complete"), std::string::npos) << err;
  const TextureImage image = read_texture_image(dir / "image.png");  // decoded whole: no truncated data
  EXPECT_EQ(image.width, 2048u);
  EXPECT_EQ(image.height, 2048u);
  EXPECT_FALSE(temporaries_left(dir.path()));
}

TEST(Interrupt, SecondInterruptEndsAtOnceWithoutTemporaries) {
  test::TempDir dir;
  EXPECT_EQ(exit_status_after(dir, "", {SIGINT, SIGINT}), 130);
  EXPECT_FALSE(temporaries_left(dir.path()));
}
#endif

}  // namespace
}  // namespace pt
