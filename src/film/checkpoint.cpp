// Saved films: the file layout (a fixed header, then the film's pixels as they are in memory) and its checks.
#include "film/checkpoint.hpp"

#include <cstring>
#include <fstream>

#include <fmt/format.h>

#include "base/atomic_file.hpp"
#include "base/errors.hpp"

namespace pt {
namespace {

constexpr char kMagic[8] = {'P', 'T', 'F', 'I', 'L', 'M', '0', '1'};

// Everything before the pixels. FilmPixel's layout is part of the format: a change of it changes the magic.
struct Header {
  char magic[8];
  u64 hash;
  u32 width, height;
  u32 samples_done;
  u32 pixel_bytes;
};
static_assert(sizeof(FilmPixel) == 32, "the checkpoint format stores FilmPixel as 32 bytes");

// FNV-1a, 64 bits: a change of any byte of the scene or settings changes the key.
u64 fnv1a(u64 hash, const std::string& bytes) {
  for (const unsigned char c : bytes) hash = (hash ^ c) * 0x100000001b3ULL;
  return hash;
}

}  // namespace

CheckpointKey checkpoint_key(const std::string& scene_text, const std::string& settings, u32 width, u32 height) {
  const u64 hash = fnv1a(fnv1a(0xcbf29ce484222325ULL, scene_text), "\n" + settings);
  return CheckpointKey{hash, width, height};
}

void write_checkpoint(const std::filesystem::path& file, const CheckpointKey& key, std::span<const FilmPixel> film, u32 samples_done) {
  Header header{};
  std::memcpy(header.magic, kMagic, sizeof(kMagic));
  header.hash = key.hash;
  header.width = key.width;
  header.height = key.height;
  header.samples_done = samples_done;
  header.pixel_bytes = sizeof(FilmPixel);
  AtomicFile out(file, "the checkpoint");
  out.write(&header, sizeof(header));
  out.write(film.data(), film.size_bytes());
  out.publish();
}

Checkpoint read_checkpoint(const std::filesystem::path& file, const CheckpointKey& key) {
  const auto refuse = [&](const std::string& why) { return InputError(fmt::format("{}: cannot resume: {}", file.string(), why)); };
  std::error_code error;
  if (!std::filesystem::is_regular_file(file, error)) throw refuse("not a file that can be read");
  std::ifstream in(file, std::ios::binary);
  Header header{};
  if (!in.read(reinterpret_cast<char*>(&header), sizeof(header)) || std::memcmp(header.magic, kMagic, sizeof(kMagic)) != 0)
    throw refuse("not a checkpoint of this program");
  if (header.pixel_bytes != sizeof(FilmPixel)) throw refuse("written by a version with another film layout");
  if (header.width != key.width || header.height != key.height)
    throw refuse(fmt::format("its film is {}x{}, this render's {}x{}", header.width, header.height, key.width, key.height));
  if (header.hash != key.hash) throw refuse("it was saved for another scene or other settings (scene text, depth, seed or number format)");
  const std::size_t pixels = static_cast<std::size_t>(header.width) * header.height;
  if (std::filesystem::file_size(file, error) != sizeof(Header) + pixels * sizeof(FilmPixel)) throw refuse("the file is cut short or too long");
  Checkpoint checkpoint;
  checkpoint.samples_done = header.samples_done;
  checkpoint.film.resize(pixels);
  if (!in.read(reinterpret_cast<char*>(checkpoint.film.data()), static_cast<std::streamsize>(pixels * sizeof(FilmPixel))))
    throw refuse("the file is cut short");
  return checkpoint;
}

}  // namespace pt
