// Saved films: a render's film and its sample count written to a file, so that the render can be resumed later.
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "kernel/integrator.hpp"

namespace pt {

// What a film may only be resumed with: the same scene text and everything else that decides each sample (size,
// depth, seed, roulette, number format). Not the sample count: a finished render can be resumed to more samples.
struct CheckpointKey {
  u64 hash = 0;
  u32 width = 0, height = 0;
  bool operator==(const CheckpointKey&) const = default;
};

// The key of a render: `scene_text` is the scene file's bytes, `settings` every other thing named above, as text.
CheckpointKey checkpoint_key(const std::string& scene_text, const std::string& settings, u32 width, u32 height);

// The same key made from the scene file, read a piece at a time: the key is made while the flattened scene is held,
// and a large scene's text (hundreds of megabytes) read whole at that point set the render's peak memory. A file that
// cannot be read counts as the bytes that could.
CheckpointKey checkpoint_key_of_file(const std::filesystem::path& scene_file, const std::string& settings, u32 width, u32 height);

struct Checkpoint {
  std::vector<FilmPixel> film;
  u32 samples_done = 0;
};

// Writes the film atomically (a temporary, synced, renamed over `file`). Throws InputError naming the file.
void write_checkpoint(const std::filesystem::path& file, const CheckpointKey& key, std::span<const FilmPixel> film, u32 samples_done);

// Reads a checkpoint written for `key`; a file that is not one, is cut short, fails its checksum, or belongs to
// another scene or settings is refused with an InputError naming the file and what is wrong.
Checkpoint read_checkpoint(const std::filesystem::path& file, const CheckpointKey& key);

}  // namespace pt
