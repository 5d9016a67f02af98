// Walks the structure of the image formats stb_image reads past the end of (image_data_check.hpp), as stb_image
// 2.27 reads them, and says what is missing. Each walk only counts bytes; only the PSD's decodes pixels, one at a
// time, for the one value stb cannot take (psd_matte_problem).
#include "image/image_data_check.hpp"

#include <array>
#include <cstdlib>
#include <cstring>

#include <fmt/format.h>

#include "base/errors.hpp"

namespace pt {
namespace {

// A cursor over the bytes; every read past the end is noted, not performed.
class ByteWalk {
 public:
  explicit ByteWalk(std::span<const u8> bytes) : bytes_(bytes) {}
  std::size_t position() const { return position_; }
  std::size_t size() const { return bytes_.size(); }
  bool has(u64 count) const { return count <= bytes_.size() - position_; }
  // The next byte, or 0 past the end (then `has` was false: callers check before they trust it).
  unsigned byte() { return position_ < bytes_.size() ? bytes_[position_++] : 0u; }
  unsigned byte_at(std::size_t at) const { return at < bytes_.size() ? bytes_[at] : 0u; }
  u64 le16(std::size_t at) const { return byte_at(at) | (u64{byte_at(at + 1)} << 8); }
  u64 le32(std::size_t at) const { return le16(at) | (le16(at + 2) << 16); }
  u64 be16(std::size_t at) const { return (u64{byte_at(at)} << 8) | byte_at(at + 1); }
  u64 be32(std::size_t at) const { return (be16(at) << 16) | be16(at + 2); }
  void seek(u64 at) { position_ = at < bytes_.size() ? static_cast<std::size_t>(at) : bytes_.size(); }
  // Skips `count` bytes; false when fewer are left.
  bool skip(u64 count) {
    if (!has(count)) {
      position_ = bytes_.size();
      return false;
    }
    position_ += static_cast<std::size_t>(count);
    return true;
  }

 private:
  std::span<const u8> bytes_;
  std::size_t position_ = 0;
};

std::string short_by(const char* what, u64 needed, std::size_t size) {
  return fmt::format("truncated: {} would end at byte {}, the image has {} bytes", what, needed, size);
}

bool starts_with(std::span<const u8> bytes, const char* magic) {
  const std::size_t n = std::strlen(magic);
  return bytes.size() >= n && std::memcmp(bytes.data(), magic, n) == 0;
}

// Radiance RGBE: header lines up to an empty one, the resolution line "-Y H +X W", then H scanlines, each either W
// flat four-byte pixels or (for 8 <= W < 32768, starting 2 2 W/256 W%256) four channels of run-length data. stb
// takes a scanline that does not start so as the first of flat pixels to the end of the image.
// The next line of a Radiance header as stb_image 2.27 reads it (stbi__hdr_gettoken): up to a newline, at most 1023
// characters (the rest of a longer line skipped), and then a C string, so that a line starting with a NUL byte is
// empty and ends the header. Read the same way here, or a header stb ends early would be taken for another.
std::string radiance_token(ByteWalk& walk) {
  std::string token;
  unsigned c = walk.byte();
  while (walk.has(1) && c != '\n') {
    token += static_cast<char>(c);
    if (token.size() == 1023) {
      while (walk.has(1) && walk.byte() != '\n') {
      }
      break;
    }
    c = walk.byte();
  }
  return token.substr(0, token.find('\0'));
}

std::optional<std::string> radiance_problem(std::span<const u8> bytes) {
  ByteWalk walk(bytes);
  // The header: its first line, then lines until an empty one.
  radiance_token(walk);
  for (;;) {
    if (!walk.has(1)) return "truncated: the Radiance header has no end (an empty line)";
    if (radiance_token(walk).empty()) break;
  }
  // "-Y height +X width", read as stb reads it (strtol); a layout it does not take it refuses.
  const std::string line = radiance_token(walk);
  if (line.compare(0, 3, "-Y ") != 0) return std::nullopt;
  // stb keeps strtol's long in an int: the same conversion here (modulo 2^32), so that both see the same size.
  char* after = nullptr;
  const int rows = static_cast<int>(std::strtol(line.c_str() + 3, &after, 10));
  while (*after == ' ') ++after;
  if (std::strncmp(after, "+X ", 3) != 0) return std::nullopt;
  const int columns = static_cast<int>(std::strtol(after + 3, nullptr, 10));
  if (rows <= 0 || columns <= 0 || rows > (1 << 24) || columns > (1 << 24)) return std::nullopt;  // stb refuses these itself
  const u64 height = static_cast<u64>(rows), width = static_cast<u64>(columns);
  const u64 flat_bytes = u64{4} * width * height;
  for (u64 row = 0; row < height; ++row) {
    const bool run_length = width >= 8 && width < 32768 && walk.byte_at(walk.position()) == 2 && walk.byte_at(walk.position() + 1) == 2 &&
                            (walk.byte_at(walk.position() + 2) & 0x80) == 0;
    if (!run_length) {
      const u64 rest = flat_bytes - u64{4} * width * row;
      if (!walk.has(rest)) return short_by("the rest of the Radiance image, as flat pixels,", walk.position() + rest, bytes.size());
      return std::nullopt;
    }
    if (!walk.has(4)) return short_by("a Radiance scanline", walk.position() + 4, bytes.size());
    if ((walk.byte_at(walk.position() + 2) << 8 | walk.byte_at(walk.position() + 3)) != width)
      return std::nullopt;  // stb refuses a scanline of the wrong width itself
    walk.skip(4);
    for (int channel = 0; channel < 4; ++channel) {
      for (u64 done = 0; done < width;) {
        if (!walk.has(1))
          return fmt::format("truncated: Radiance scanline {} of {} ends at byte {} inside its run-length data", row + 1, height, bytes.size());
        unsigned count = walk.byte();
        const bool run = count > 128;
        if (run) count -= 128;
        // stb_image 2.27 loops for ever on an empty run.
        if (count == 0) return fmt::format("corrupt: Radiance scanline {} has a run of length 0 at byte {}", row + 1, walk.position() - 1);
        if (count > width - done) return std::nullopt;  // stb refuses a run past the scanline itself
        if (!walk.skip(run ? 1 : count))
          return fmt::format("truncated: Radiance scanline {} of {} ends at byte {} inside its run-length data", row + 1, height, bytes.size());
        done += count;
      }
    }
  }
  return std::nullopt;
}

// TGA: an 18-byte header, an ID, a palette, then pixels, plain or in run-length packets.
std::optional<std::string> tga_problem(std::span<const u8> bytes) {
  ByteWalk walk(bytes);
  if (!walk.has(18)) return short_by("a TGA header", 18, bytes.size());
  const unsigned id_length = walk.byte_at(0), indexed = walk.byte_at(1), type = walk.byte_at(2);
  const u64 palette_start = walk.le16(3), palette_length = walk.le16(5), palette_bits = walk.byte_at(7);
  const u64 width = walk.le16(12), height = walk.le16(14), bits = walk.byte_at(16);
  if ((type & 7) < 1 || (type & 7) > 3) return std::nullopt;
  const bool run_length = type >= 8;
  const auto bytes_of = [](u64 bits_per_value) { return bits_per_value == 15 || bits_per_value == 16 ? u64{2} : (bits_per_value + 7) / 8; };
  walk.seek(18);
  if (!walk.skip(id_length)) return short_by("the TGA's image ID", 18 + u64{id_length}, bytes.size());
  u64 pixel_bytes = bytes_of(bits);
  if (indexed) {
    const u64 palette_end = walk.position() + palette_start + palette_length * bytes_of(palette_bits);
    if (!walk.skip(palette_start + palette_length * bytes_of(palette_bits))) return short_by("the TGA's palette", palette_end, bytes.size());
    pixel_bytes = bits == 8 ? 1 : 2;
  }
  const u64 pixels = width * height;
  if (!run_length) {
    const u64 needed = walk.position() + pixels * pixel_bytes;
    return walk.has(pixels * pixel_bytes) ? std::nullopt : std::optional(short_by("the TGA's pixels", needed, bytes.size()));
  }
  for (u64 done = 0; done < pixels;) {
    if (!walk.has(1)) return fmt::format("truncated: the TGA's run-length data ends at byte {} after {} of {} pixels", bytes.size(), done, pixels);
    const unsigned packet = walk.byte();
    const u64 count = (packet & 127) + 1;
    if (!walk.skip(packet & 128 ? pixel_bytes : count * pixel_bytes))
      return fmt::format("truncated: the TGA's run-length data ends at byte {} after {} of {} pixels", bytes.size(), done, pixels);
    done += count;
  }
  return std::nullopt;
}

// BMP: rows of 4-byte multiples from the pixel data's offset.
std::optional<std::string> bmp_problem(std::span<const u8> bytes) {
  ByteWalk walk(bytes);
  if (!walk.has(26)) return short_by("a BMP header", 26, bytes.size());
  const u64 offset = walk.le32(10), header_size = walk.le32(14);
  u64 width = 0, height = 0, bits = 0;
  if (header_size == 12) {
    width = walk.le16(18), height = walk.le16(20), bits = walk.le16(24);
  } else {
    if (!walk.has(30)) return short_by("a BMP header", 30, bytes.size());
    width = walk.le32(18);
    const auto signed_height = static_cast<std::int32_t>(walk.le32(22));
    height = signed_height < 0 ? u64{0} - static_cast<std::int64_t>(signed_height) : static_cast<u64>(signed_height);
    bits = walk.le16(28);
  }
  if (width > (u64{1} << 24) || height > (u64{1} << 24) || bits == 0 || bits > 32) return std::nullopt;  // stb refuses these itself
  // Every row is padded to four bytes; the last one's padding may be left out.
  const u64 row_bytes = (width * bits + 31) / 32 * 4, needed = height == 0 ? offset : offset + row_bytes * (height - 1) + (width * bits + 7) / 8;
  return needed <= bytes.size() ? std::nullopt : std::optional(short_by("the BMP's pixel rows", needed, bytes.size()));
}

// stb_image takes at most 2^24 texels on a side (STBI_MAX_DIMENSIONS) and a largest value of 65535.
constexpr u64 kLargestPnmNumber = u64{1} << 24;

// Binary PGM and PPM: "P5" or "P6", width, height and the largest value, separated by white space and comments,
// one white-space byte, then the samples (two bytes each above 255).
std::optional<std::string> pnm_problem(std::span<const u8> bytes) {
  ByteWalk walk(bytes);
  const u64 channels = bytes[1] == '5' ? 1 : 3;
  walk.seek(2);
  u64 values[3] = {};
  const char* names[3] = {"width", "height", "largest value"};
  unsigned c = walk.byte();
  for (int i = 0; i < 3; ++i) {
    for (;;) {
      while (walk.has(1) && (c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r')) c = walk.byte();
      if (!walk.has(1) || c != '#') break;
      while (walk.has(1) && c != '\n' && c != '\r') c = walk.byte();
    }
    // stb reads a missing number as 0, and the samples after it as zeros.
    if (c < '0' || c > '9') return fmt::format("{}: the PNM header has no {}", walk.has(1) ? "corrupt" : "truncated", names[i]);
    while (c >= '0' && c <= '9') {
      values[i] = values[i] * 10 + (c - '0');
      // stb reads these numbers into an int, past whose range it overflows: beyond any image's size, refused here.
      if (values[i] > kLargestPnmNumber) return fmt::format("corrupt: the PNM's {} is more than {}", names[i], kLargestPnmNumber);
      c = walk.byte();
    }
  }
  if (values[2] == 0) return "corrupt: the PNM's largest value is 0";
  if (values[2] > 65535) return std::nullopt;  // stb refuses it itself
  const u64 sample_bytes = values[2] > 255 ? 2 : 1;
  const u64 needed = walk.position() + values[0] * values[1] * channels * sample_bytes;
  return needed <= bytes.size() ? std::nullopt : std::optional(short_by("the PNM's samples", needed, bytes.size()));
}

// One channel plane of a PSD as stb_image 2.27 decodes it into eight-bit samples: plain (the high byte of a 16-bit
// sample) or PackBits, whose samples are always single bytes there. Reads one sample at a time, so that four planes
// can be read side by side without holding any of them.
class PsdPlane {
 public:
  PsdPlane(std::span<const u8> bytes, std::size_t start, bool run_length, u64 sample_bytes)
      : bytes_(bytes), at_(start), run_length_(run_length), sample_bytes_(sample_bytes) {}
  // The next sample; the caller has checked (psd_problem's walk) that the plane's data is all there.
  unsigned next() {
    if (!run_length_) {
      const unsigned sample = at_ < bytes_.size() ? bytes_[at_] : 0u;
      at_ += sample_bytes_;
      return sample;
    }
    while (left_ == 0) {
      const unsigned length = at_ < bytes_.size() ? bytes_[at_++] : 0u;
      if (length == 128) continue;
      literal_ = length < 128;
      left_ = literal_ ? length + 1 : 257 - length;
      if (!literal_) repeated_ = at_ < bytes_.size() ? bytes_[at_++] : 0u;
    }
    --left_;
    if (!literal_) return repeated_;
    return at_ < bytes_.size() ? bytes_[at_++] : 0u;
  }

 private:
  std::span<const u8> bytes_;
  std::size_t at_;
  bool run_length_;
  u64 sample_bytes_;
  bool literal_ = false;
  unsigned left_ = 0, repeated_ = 0;
};

// stb_image takes a PSD's fourth channel for alpha and its colours for colours composited over white, which it
// removes: colour' = (colour - 255 (1 - a)) / a. A colour below 255 - alpha (darker than white behind that alpha
// allows, which no composite over white is) becomes negative there, converted to a byte out of its range
// (undefined behaviour; found by fuzz/fuzz_texture_image). In whole numbers, so that no rounding decides.
std::optional<std::string> psd_matte_problem(std::array<PsdPlane, 4> planes, u64 width, u64 pixels) {
  static constexpr const char* kColours[3] = {"red", "green", "blue"};
  for (u64 i = 0; i < pixels; ++i) {
    const unsigned colour[3] = {planes[0].next(), planes[1].next(), planes[2].next()}, alpha = planes[3].next();
    if (alpha == 0 || alpha == 255) continue;
    for (int c = 0; c < 3; ++c)
      if (colour[c] + alpha < 255)
        return fmt::format("corrupt: the PSD's pixel ({}, {}) has {} {} under alpha {}, darker than a colour composited over white can be", i % width,
                           i / width, kColours[c], colour[c], alpha);
  }
  return std::nullopt;
}

// Photoshop: a 26-byte header, three sections of given lengths, then the first four channels' planes, plain or as
// PackBits rows after a table of the rows' lengths.
std::optional<std::string> psd_problem(std::span<const u8> bytes) {
  ByteWalk walk(bytes);
  if (!walk.has(26)) return short_by("a PSD header", 26, bytes.size());
  const u64 channels = walk.be16(12), height = walk.be32(14), width = walk.be32(18), depth = walk.be16(22);
  if (channels > 16 || (depth != 8 && depth != 16) || width > (u64{1} << 24) || height > (u64{1} << 24)) return std::nullopt;
  walk.seek(26);
  for (const char* section : {"colour mode data", "image resources", "layer and mask data"}) {
    if (!walk.has(4)) return short_by(fmt::format("the PSD's {} length", section).c_str(), walk.position() + 4, bytes.size());
    const u64 length = walk.be32(walk.position());
    walk.skip(4);
    if (!walk.skip(length)) return short_by(fmt::format("the PSD's {}", section).c_str(), walk.position() + length, bytes.size());
  }
  if (!walk.has(2)) return short_by("the PSD's compression", walk.position() + 2, bytes.size());
  const u64 compression = walk.be16(walk.position());
  walk.skip(2);
  const u64 pixels = width * height, read_channels = channels < 4 ? channels : 4;
  if (compression > 1 || pixels == 0) return std::nullopt;  // stb refuses it itself
  std::array<std::size_t, 4> starts{};                      // where each channel's plane starts
  if (compression == 0) {
    const u64 plane_bytes = pixels * (depth / 8);
    const u64 needed = walk.position() + read_channels * plane_bytes;
    if (needed > bytes.size()) return short_by("the PSD's channels", needed, bytes.size());
    for (u64 channel = 0; channel < read_channels; ++channel) starts[channel] = static_cast<std::size_t>(walk.position() + channel * plane_bytes);
  } else {
    if (!walk.skip(height * channels * 2)) return short_by("the PSD's row lengths", walk.position() + height * channels * 2, bytes.size());
    for (u64 channel = 0; channel < read_channels; ++channel) {
      starts[channel] = walk.position();
      for (u64 done = 0; done < pixels;) {
        if (!walk.has(1))
          return fmt::format("truncated: the PSD's channel {} ends at byte {} after {} of {} samples", channel, bytes.size(), done, pixels);
        const unsigned length = walk.byte();
        if (length == 128) continue;
        const u64 count = length < 128 ? length + 1 : 257 - length;
        if (count > pixels - done) return std::nullopt;  // stb refuses the run itself
        if (!walk.skip(length < 128 ? count : 1))
          return fmt::format("truncated: the PSD's channel {} ends at byte {} after {} of {} samples", channel, bytes.size(), done, pixels);
        done += count;
      }
    }
  }
  if (channels < 4) return std::nullopt;
  const auto plane = [&](int channel) { return PsdPlane(bytes, starts[channel], compression == 1, depth / 8); };
  return psd_matte_problem({plane(0), plane(1), plane(2), plane(3)}, width, pixels);
}

// GIF: a header, a screen descriptor and colour table, then blocks up to the first image's data, which ends with an
// empty sub-block.
std::optional<std::string> gif_problem(std::span<const u8> bytes) {
  ByteWalk walk(bytes);
  if (!walk.has(13)) return short_by("a GIF header", 13, bytes.size());
  const auto colour_table = [](unsigned flags) { return flags & 0x80 ? u64{3} << ((flags & 7) + 1) : u64{0}; };
  walk.seek(13);
  if (!walk.skip(colour_table(walk.byte_at(10)))) return short_by("the GIF's colour table", 13 + colour_table(walk.byte_at(10)), bytes.size());
  const auto sub_blocks = [&walk]() {
    for (;;) {
      if (!walk.has(1)) return false;
      const unsigned length = walk.byte();
      if (length == 0) return true;
      if (!walk.skip(length)) return false;
    }
  };
  const std::string truncated = fmt::format("truncated: the GIF ends at byte {} before its first image is complete", bytes.size());
  for (;;) {
    if (!walk.has(1)) return truncated;
    const unsigned block = walk.byte();
    if (block == 0x21) {  // an extension: its label, then sub-blocks
      if (!walk.skip(1) || !sub_blocks()) return truncated;
    } else if (block == 0x2C) {  // an image: its descriptor, a colour table, the code size, then sub-blocks
      if (!walk.has(9)) return truncated;
      const unsigned flags = walk.byte_at(walk.position() + 8);
      if (!walk.skip(9) || !walk.skip(colour_table(flags)) || !walk.skip(1) || !sub_blocks()) return truncated;
      return std::nullopt;
    } else {
      return std::nullopt;  // the trailer, or a block stb refuses itself
    }
  }
}

// JPEG: segments (a marker, then a big-endian length that counts itself) up to each scan, the scan's entropy-coded
// data up to the next marker (a data byte FF is followed by 00, or is a restart marker), and so on to the
// end-of-image marker FF D9, which stb needs: a file cut short has none. The segments are walked, not searched,
// since an Exif segment may hold a whole thumbnail JPEG, end-of-image marker included. stb_image 2.27 keeps its
// Huffman and quantisation tables in memory it never clears, so a scan that uses a table no segment before it
// defined decodes with uninitialised memory (its Huffman codes then index past the table's 256 values; found by
// fuzz/fuzz_texture_image): such a scan is refused.
std::optional<std::string> jpeg_problem(std::span<const u8> bytes) {
  ByteWalk walk(bytes);
  walk.seek(2);
  bool dc_table[4] = {}, ac_table[4] = {}, quantisation_table[4] = {};
  struct FrameComponent {
    unsigned id, table;
  };
  std::vector<FrameComponent> frame;
  bool progressive = false, scanned = false, framed = false;
  for (;;) {
    if (!walk.has(2))
      return fmt::format("truncated: the JPEG ends at byte {} {}", bytes.size(),
                         scanned ? "without its end-of-image marker" : "before its image data");
    if (walk.byte() != 0xFF) {
      // Not a marker: before the frame stb skips such bytes (padding some files have) up to the next 0xFF; after
      // it, stb refuses the file itself.
      if (framed) return std::nullopt;
      continue;
    }
    unsigned marker = walk.byte();
    while (marker == 0xFF && walk.has(1)) marker = walk.byte();          // fill bytes
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) continue;  // markers without a segment
    if (marker == 0xD9) return std::nullopt;                             // the end (stb refuses an image without a scan)
    if (!walk.has(2)) return fmt::format("truncated: the JPEG ends at byte {} inside a segment's length", bytes.size());
    const std::size_t segment = walk.position();
    const u64 length = walk.be16(segment);
    if (length < 2) return std::nullopt;
    if (!walk.skip(length)) return fmt::format("truncated: the JPEG ends at byte {} inside a segment of {} bytes", bytes.size(), length);
    const std::size_t end = segment + static_cast<std::size_t>(length);
    if (marker == 0xDB) {  // quantisation tables: a precision and number byte, then 64 values of 1 or 2 bytes
      for (std::size_t at = segment + 2; at < end;) {
        const unsigned precision = walk.byte_at(at) >> 4, table = walk.byte_at(at) & 15;
        if (table > 3) return std::nullopt;  // stb refuses it
        quantisation_table[table] = true;
        at += 1 + (precision ? 128 : 64);
      }
    } else if (marker == 0xC4) {  // Huffman tables: a class and number byte, 16 counts, the values
      for (std::size_t at = segment + 2; at < end;) {
        const unsigned table_class = walk.byte_at(at) >> 4, table = walk.byte_at(at) & 15;
        if (table_class > 1 || table > 3) return std::nullopt;  // stb refuses it
        (table_class == 0 ? dc_table : ac_table)[table] = true;
        std::size_t codes = 0;
        for (std::size_t i = 0; i < 16; ++i) codes += walk.byte_at(at + 1 + i);
        at += 17 + codes;
      }
    } else if (marker == 0xC0 || marker == 0xC1 || marker == 0xC2) {  // the frame: its components' quantisation tables
      progressive = marker == 0xC2;
      framed = true;
      frame.clear();
      const unsigned components = walk.byte_at(segment + 7);
      for (unsigned c = 0; c < components; ++c) frame.push_back({walk.byte_at(segment + 8 + 3 * c), walk.byte_at(segment + 10 + 3 * c)});
    } else if (marker == 0xDA) {  // a scan: its components, their Huffman tables, the spectral selection
      scanned = true;
      const unsigned components = walk.byte_at(segment + 2);
      const unsigned spectral_start = walk.byte_at(segment + 3 + 2 * components), high_bit = walk.byte_at(segment + 5 + 2 * components) >> 4;
      for (unsigned c = 0; c < components; ++c) {
        const unsigned id = walk.byte_at(segment + 3 + 2 * c), tables = walk.byte_at(segment + 4 + 2 * c);
        const unsigned dc = tables >> 4, ac = tables & 15;
        if (dc > 3 || ac > 3) return std::nullopt;  // stb refuses it
        // Baseline scans decode both tables; a progressive scan its DC table in a first DC scan, its AC one otherwise.
        const bool needs_dc = !progressive || (spectral_start == 0 && high_bit == 0), needs_ac = !progressive || spectral_start != 0;
        const auto undefined = [&](const char* kind, unsigned table, const char* segment_kind) {
          return fmt::format("corrupt: the JPEG's scan at byte {} uses {} table {}, which no {} segment before it defines", segment - 2, kind, table,
                             segment_kind);
        };
        if (needs_dc && !dc_table[dc]) return undefined("DC Huffman", dc, "DHT");
        if (needs_ac && !ac_table[ac]) return undefined("AC Huffman", ac, "DHT");
        for (const FrameComponent& f : frame)
          if (f.id == id && (f.table > 3 || !quantisation_table[f.table])) return undefined("quantisation", f.table, "DQT");
      }
      // The entropy-coded data runs to the next marker: 0xFF followed by neither 0 (a stuffed 0xFF) nor a restart.
      std::size_t at = end;
      while (at + 1 < bytes.size() && !(bytes[at] == 0xFF && bytes[at + 1] != 0 && !(bytes[at + 1] >= 0xD0 && bytes[at + 1] <= 0xD7))) ++at;
      if (at + 1 >= bytes.size()) return fmt::format("truncated: the JPEG ends at byte {} without its end-of-image marker", bytes.size());
      walk.seek(at);
    }
  }
}

// PNG: chunks of a 4-byte length, a 4-byte type, the data and a 4-byte CRC, up to IEND. stb_image grows its buffer
// for the compressed data to a data chunk's length before it reads the chunk (2 GiB for a 200-byte file that claims
// so much), so a chunk that runs past the end of the file is refused first. (What zlib's stream holds, stb checks.)
std::optional<std::string> png_problem(std::span<const u8> bytes) {
  ByteWalk walk(bytes);
  for (std::size_t at = 8;;) {
    if (at > bytes.size() || bytes.size() - at < 8)
      return fmt::format("truncated: the PNG ends at byte {}, inside a chunk's length and type", bytes.size());
    const u64 length = walk.be32(at);
    const std::string type(reinterpret_cast<const char*>(bytes.data() + at + 4), 4);
    if (length > bytes.size() - at - 8 || bytes.size() - at - 8 - length < 4)
      return fmt::format("truncated: the PNG's chunk '{}' at byte {} would end at byte {}, the image has {} bytes", escape_control_characters(type),
                         at, at + 12 + length, bytes.size());
    if (type == "IEND") return std::nullopt;
    at += 12 + static_cast<std::size_t>(length);
  }
}

}  // namespace

std::optional<std::string> image_header_problem(std::span<const u8> start) {
  if (start.size() < 2 || start[0] != 'P' || (start[1] != '5' && start[1] != '6')) return std::nullopt;
  const std::optional<std::string> problem = pnm_problem(start);
  // Cut short within the first bytes is a fault of the header only where the header itself is cut.
  if (problem && problem->starts_with("truncated: the PNM's samples")) return std::nullopt;
  if (problem && problem->starts_with("truncated") && start.size() >= kImageHeaderBytes)
    return fmt::format("corrupt: the PNM header runs past its first {} bytes", kImageHeaderBytes);
  return problem;
}

std::optional<std::vector<u8>> png_without_empty_data_chunks(std::span<const u8> bytes) {
  static constexpr u8 kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kSignature, 8) != 0) return std::nullopt;
  // Each chunk: a 4-byte length, a 4-byte type, the data, a 4-byte CRC (which stb does not check).
  std::vector<std::pair<std::size_t, std::size_t>> empty;  // where each empty IDAT starts, and its bytes (12, or fewer at the end)
  ByteWalk walk(bytes);
  for (std::size_t at = 8; at + 8 <= bytes.size();) {  // stb reads a chunk whose length and type are there
    const u64 length = walk.be32(at);
    if (length == 0 && std::memcmp(bytes.data() + at + 4, "IDAT", 4) == 0) empty.emplace_back(at, std::min<std::size_t>(12, bytes.size() - at));
    if (at + 12 > bytes.size() || length > bytes.size() - at - 12) break;
    at += 12 + static_cast<std::size_t>(length);
  }
  if (empty.empty()) return std::nullopt;
  std::vector<u8> kept;
  kept.reserve(bytes.size());
  std::size_t from = 0;
  for (const auto& [at, size] : empty) {
    kept.insert(kept.end(), bytes.begin() + static_cast<std::ptrdiff_t>(from), bytes.begin() + static_cast<std::ptrdiff_t>(at));
    from = at + size;
  }
  kept.insert(kept.end(), bytes.begin() + static_cast<std::ptrdiff_t>(from), bytes.end());
  return kept;
}

std::optional<std::string> image_data_problem(std::span<const u8> bytes) {
  if (bytes.size() < 2) return std::nullopt;
  if (starts_with(bytes, "#?")) return radiance_problem(bytes);
  if (bytes[0] == 'B' && bytes[1] == 'M') return bmp_problem(bytes);
  if (bytes[0] == 'P' && (bytes[1] == '5' || bytes[1] == '6')) return pnm_problem(bytes);
  if (starts_with(bytes, "8BPS")) return psd_problem(bytes);
  if (starts_with(bytes, "GIF8")) return gif_problem(bytes);
  if (bytes[0] == 0xFF && bytes[1] == 0xD8) return jpeg_problem(bytes);
  static constexpr u8 kPng[4] = {0x89, 'P', 'N', 'G'};
  if (bytes.size() >= 4 && std::memcmp(bytes.data(), kPng, 4) == 0) return png_problem(bytes);
  // TGA has no magic number: stb takes what its header test accepts as one (image types 1-3 and 9-11).
  const unsigned type = bytes.size() >= 3 ? bytes[2] : 0;
  if ((type >= 1 && type <= 3) || (type >= 9 && type <= 11)) return tga_problem(bytes);
  return std::nullopt;
}

}  // namespace pt
