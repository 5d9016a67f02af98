// Finding exact duplicates among a scene's primitives and a mesh's triangles, which are dropped before the BVH is
// built: copies of one shape have the same bounds, so no split separates them and every ray that reaches them
// tests them all (100,000 copies of one sphere traced about 5,000 rays a second).
#pragma once

#include <bit>
#include <cstddef>
#include <unordered_map>
#include <vector>

#include "kernel/platform.hpp"

namespace pt {

// Hashes the bit patterns of numbers (so -0 and 0 differ, as the comparisons that confirm a duplicate may not).
class BitHash {
 public:
  void add(double x) { add_bits(std::bit_cast<u64>(x)); }
  void add_bits(u64 bits) {
    state_ ^= bits + 0x9e3779b97f4a7c15ull + (state_ << 6) + (state_ >> 2);
    state_ *= 0xff51afd7ed558ccdull;
  }
  u64 value() const { return state_ ^ (state_ >> 33); }

 private:
  u64 state_ = 0xcbf29ce484222325ull;
};

// For `count` items, which to keep: all but those `same` as an earlier item, found through `hash` (items of equal
// hashes that `same` tells apart are all kept).
template <class Hash, class Same>
std::vector<char> first_of_each(std::size_t count, Hash hash, Same same) {
  std::vector<char> keep(count, 1);
  std::unordered_map<u64, std::size_t> first;
  first.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const auto [at, inserted] = first.try_emplace(hash(i), i);
    if (!inserted && same(at->second, i)) keep[i] = 0;
  }
  return keep;
}

}  // namespace pt
