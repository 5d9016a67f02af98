// Saved films: the file layout (a fixed header, then the film's pixels as they are in memory, then a checksum of
// both) and its checks.
#include "film/checkpoint.hpp"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <string_view>

#include <fmt/format.h>

#include "base/atomic_file.hpp"
#include "base/errors.hpp"

namespace pt {
namespace {

constexpr char kMagic[8] = {'P', 'T', 'F', 'I', 'L', 'M', '0', '4'};
constexpr char kMagicOfOddSampleSums[8] = {'P', 'T', 'F', 'I', 'L', 'M', '0', '3'};
constexpr char kMagicOf32BytePixels[8] = {'P', 'T', 'F', 'I', 'L', 'M', '0', '2'};
constexpr char kMagicWithoutChecksum[8] = {'P', 'T', 'F', 'I', 'L', 'M', '0', '1'};

// Everything before the pixels. FilmPixel's layout is part of the format: a change of it changes the magic.
struct Header {
  char magic[8];
  u64 hash;
  u32 width, height;
  u32 samples_done;
  u32 pixel_bytes;
};
static_assert(sizeof(FilmPixel) == 40, "the checkpoint format stores FilmPixel as 40 bytes");

// CRC-32 (zlib's) of the header and the film, stored after the film: a flipped bit anywhere is found. zlib takes
// lengths as unsigned int, so a large film is summed in pieces.
u32 checksum(const Header& header, std::span<const FilmPixel> film) {
  uLong crc = crc32(0L, reinterpret_cast<const Bytef*>(&header), sizeof(header));
  const auto* bytes = reinterpret_cast<const Bytef*>(film.data());
  for (std::size_t left = film.size_bytes(); left > 0;) {
    const std::size_t piece = std::min<std::size_t>(left, 1u << 30);
    crc = crc32(crc, bytes, static_cast<uInt>(piece));
    bytes += piece;
    left -= piece;
  }
  return static_cast<u32>(crc);
}

// FNV-1a, 64 bits: a change of any byte of the scene or settings changes the key.
u64 fnv1a(u64 hash, std::string_view bytes) {
  for (const unsigned char c : bytes) hash = (hash ^ c) * 0x100000001b3ULL;
  return hash;
}

constexpr u64 kFnvOffsetBasis = 0xcbf29ce484222325ULL;

// The key once the scene's bytes are folded into `scene_hash`.
CheckpointKey key_of(u64 scene_hash, const std::string& settings, u32 width, u32 height) {
  return CheckpointKey{fnv1a(scene_hash, "\n" + settings), width, height};
}

}  // namespace

CheckpointKey checkpoint_key(const std::string& scene_text, const std::string& settings, u32 width, u32 height) {
  return key_of(fnv1a(kFnvOffsetBasis, scene_text), settings, width, height);
}

CheckpointKey checkpoint_key_of_file(const std::filesystem::path& scene_file, const std::string& settings, u32 width, u32 height) {
  std::ifstream in(scene_file, std::ios::binary);
  std::vector<char> piece(1u << 20);
  u64 hash = kFnvOffsetBasis;
  while (in) {
    in.read(piece.data(), static_cast<std::streamsize>(piece.size()));
    hash = fnv1a(hash, std::string_view(piece.data(), static_cast<std::size_t>(in.gcount())));
  }
  return key_of(hash, settings, width, height);
}

void write_checkpoint(const std::filesystem::path& file, const CheckpointKey& key, std::span<const FilmPixel> film, u32 samples_done) {
  Header header{};
  std::memcpy(header.magic, kMagic, sizeof(kMagic));
  header.hash = key.hash;
  header.width = key.width;
  header.height = key.height;
  header.samples_done = samples_done;
  header.pixel_bytes = sizeof(FilmPixel);
  const u32 sum = checksum(header, film);
  AtomicFile out(file, "the checkpoint");
  out.write(&header, sizeof(header));
  out.write(film.data(), film.size_bytes());
  out.write(&sum, sizeof(sum));
  out.publish();
}

Checkpoint read_checkpoint(const std::filesystem::path& file, const CheckpointKey& key) {
  const auto refuse = [&](const std::string& why) { return InputError(fmt::format("{}: cannot resume: {}", file.string(), why)); };
  std::error_code error;
  if (!std::filesystem::is_regular_file(file, error)) throw refuse("not a file that can be read");
  std::ifstream in(file, std::ios::binary);
  Header header{};
  if (!in.read(reinterpret_cast<char*>(&header), sizeof(header))) throw refuse("not a checkpoint of this program");
  if (std::memcmp(header.magic, kMagicWithoutChecksum, sizeof(kMagic)) == 0) throw refuse("written by an older version, without a checksum");
  if (std::memcmp(header.magic, kMagicOf32BytePixels, sizeof(kMagic)) == 0) throw refuse("written by an older version, without adaptive sampling's sums");
  if (std::memcmp(header.magic, kMagicOfOddSampleSums, sizeof(kMagic)) == 0)
    throw refuse("written by an older version, whose adaptive sampling kept other sums");
  if (std::memcmp(header.magic, kMagic, sizeof(kMagic)) != 0) throw refuse("not a checkpoint of this program");
  if (header.pixel_bytes != sizeof(FilmPixel)) throw refuse("written by a version with another film layout");
  if (header.width != key.width || header.height != key.height)
    throw refuse(fmt::format("its film is {}x{}, this render's {}x{}", header.width, header.height, key.width, key.height));
  if (header.hash != key.hash) throw refuse("it was saved for another scene or other settings (scene text, depth, seed or number format)");
  const std::size_t pixels = static_cast<std::size_t>(header.width) * header.height;
  if (std::filesystem::file_size(file, error) != sizeof(Header) + pixels * sizeof(FilmPixel) + sizeof(u32)) throw refuse("the file is cut short or too long");
  Checkpoint checkpoint;
  checkpoint.samples_done = header.samples_done;
  checkpoint.film.resize(pixels);
  u32 stored = 0;
  if (!in.read(reinterpret_cast<char*>(checkpoint.film.data()), static_cast<std::streamsize>(pixels * sizeof(FilmPixel))) ||
      !in.read(reinterpret_cast<char*>(&stored), sizeof(stored)))
    throw refuse("the file is cut short");
  if (stored != checksum(header, checkpoint.film)) throw refuse("its checksum does not match its content: the file is corrupt");
  return checkpoint;
}

}  // namespace pt
