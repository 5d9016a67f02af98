// Finding exact duplicates among a scene's primitives and a mesh's triangles, which are dropped before the BVH is
// built: copies of one shape have the same bounds, so no split separates them and every ray that reaches them
// tests them all (100,000 copies of one sphere traced about 5,000 rays a second).
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <utility>
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

// For `count` items, which to keep: all but those `same` as the first item of their hash (items of equal hashes
// that `same` tells apart are all kept). The items are sorted by hash rather than put in a hash table: 16 bytes an
// item, where a table of a million scene primitives took about 50.
template <class Hash, class Same>
std::vector<char> first_of_each(std::size_t count, Hash hash, Same same) {
  std::vector<char> keep(count, 1);
  std::vector<std::pair<u64, std::size_t>> by_hash;
  by_hash.reserve(count);
  for (std::size_t i = 0; i < count; ++i) by_hash.emplace_back(hash(i), i);
  std::sort(by_hash.begin(), by_hash.end());
  for (std::size_t k = 1; k < by_hash.size(); ++k) {
    std::size_t first = k - 1;  // the group's first item (its smallest index: pairs sort by index within a hash)
    while (k < by_hash.size() && by_hash[k].first == by_hash[first].first) {
      if (same(by_hash[first].second, by_hash[k].second)) keep[by_hash[k].second] = 0;
      ++k;
    }
  }
  return keep;
}

}  // namespace pt
