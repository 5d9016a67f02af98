// The compressed wide tree: the wide tree's boxes rounded outwards to a byte grid per node, children in slots by
// direction.
#include "flat/compressed_bvh_builder.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace pt {

namespace {

// A child as the compressed node is made from it: its box and what the slot will hold.
struct Child {
  std::array<float, 3> lo, hi;
  bool inner = false;
  u32 index = 0;  // an inner node's index, or a leaf's first primitive
  u32 count = 0;  // a leaf's primitives
};

constexpr u32 kLargestLeaf = 0xffffu;
// The smallest grid step, 2^-100: with it, 2^e times any reciprocal direction the kernels make (at least 2^-67,
// where a ray's direction has length at most 2^67) stays a normal float.
constexpr int kSmallestExponent = -100;

// The exponent e of the grid along one axis: the smallest (at least kSmallestExponent) with origin + 255 * 2^e at or
// beyond `hi`.
int grid_exponent(float origin, float hi) {
  int e = kSmallestExponent;
  const double extent = static_cast<double>(hi) - static_cast<double>(origin);
  if (extent > 0) e = std::max(e, static_cast<int>(std::ceil(std::log2(extent / 255.0))) - 1);
  while (e < 127 && static_cast<double>(origin) + 255.0 * std::ldexp(1.0, e) < static_cast<double>(hi)) ++e;
  return e;
}

// The byte of a lower plane (rounded down) and of an upper one (rounded up) on the grid.
u8 lower_byte(float origin, int e, float lo) {
  const double step = std::ldexp(1.0, e);
  double q = std::floor((static_cast<double>(lo) - static_cast<double>(origin)) / step);
  q = std::clamp(q, 0.0, 255.0);
  while (q > 0 && static_cast<double>(origin) + q * step > static_cast<double>(lo)) --q;
  return static_cast<u8>(q);
}
u8 upper_byte(float origin, int e, float hi) {
  const double step = std::ldexp(1.0, e);
  double q = std::ceil((static_cast<double>(hi) - static_cast<double>(origin)) / step);
  q = std::clamp(q, 0.0, 255.0);
  while (q < 255 && static_cast<double>(origin) + q * step < static_cast<double>(hi)) ++q;
  return static_cast<u8>(q);
}

// Places up to eight children in slots by direction from the node's centre (slot bit 0: +x side, bit 1: +y, bit 2:
// +z), greedily: the child and slot whose direction agree best first (Ylitie, Karras and Laine's assignment). Returns
// the child for each slot, or -1 for an empty one.
std::array<int, kCompressedWidth> assign_slots(const std::vector<Child>& children, const std::array<double, 3>& centre) {
  struct Pair {
    double agreement;
    int child, slot;
  };
  std::vector<Pair> pairs;
  for (int c = 0; c < static_cast<int>(children.size()); ++c)
    for (int s = 0; s < static_cast<int>(kCompressedWidth); ++s) {
      double agreement = 0;
      for (int a = 0; a < 3; ++a) {
        const double offset = 0.5 * (static_cast<double>(children[c].lo[a]) + static_cast<double>(children[c].hi[a])) - centre[a];
        agreement += (s >> a & 1 ? offset : -offset);
      }
      pairs.push_back(Pair{agreement, c, s});
    }
  // Stable order for equal agreements: by child, then slot, so that the tree does not depend on the sort.
  std::stable_sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.agreement > b.agreement; });
  std::array<int, kCompressedWidth> slot_child;
  slot_child.fill(-1);
  std::vector<bool> placed(children.size(), false);
  for (const Pair& p : pairs)
    if (!placed[p.child] && slot_child[p.slot] < 0) {
      placed[p.child] = true;
      slot_child[p.slot] = p.child;
    }
  return slot_child;
}

class Compressor {
 public:
  explicit Compressor(const std::vector<WideBvhNode<float>>& wide) : wide_(wide), out_(wide.size()) {}

  std::vector<CompressedWideNode> run() {
    for (std::size_t n = 0; n < wide_.size(); ++n) {
      const WideBvhNode<float>& w = wide_[n];
      std::vector<Child> children;
      for (u32 lane = 0; lane < kWideBvhWidth; ++lane) {
        const bool inner = w.inner_mask >> lane & 1, leaf = w.leaf_mask >> lane & 1;
        if (!inner && !leaf) continue;
        Child c;
        for (int a = 0; a < 3; ++a) c.lo[a] = w.bounds[a][lane], c.hi[a] = w.bounds[3 + a][lane];
        c.inner = inner;
        c.index = w.child[lane];
        c.count = inner ? 0 : w.count[lane];
        children.push_back(c);
      }
      out_[n] = make_node(children);
    }
    return std::move(out_);
  }

 private:
  // A leaf too large for one slot, as a node whose slots share its range (recursively where needed); its index.
  u32 split_leaf(const Child& leaf) {
    std::vector<Child> pieces;
    const u32 per_slot = (leaf.count + kCompressedWidth - 1) / kCompressedWidth;
    for (u32 first = 0; first < leaf.count; first += per_slot) {
      Child piece = leaf;
      piece.index = leaf.index + first;
      piece.count = std::min(per_slot, leaf.count - first);
      pieces.push_back(piece);
    }
    const CompressedWideNode node = make_node(pieces);
    out_.push_back(node);
    return static_cast<u32>(out_.size() - 1);
  }

  CompressedWideNode make_node(std::vector<Child> children) {
    CompressedWideNode node{};
    CompressedBoxes& boxes = node.boxes;
    // Empty slots: lo bytes 255 and hi bytes 0, a box no ray enters, and count 0 besides.
    for (u32 p = 0; p < 6; ++p) boxes.planes[2 * p] = boxes.planes[2 * p + 1] = p < 3 ? 0xffffffffu : 0u;
    if (children.empty()) return node;
    for (Child& c : children)
      if (!c.inner && c.count > kLargestLeaf) {
        c.index = split_leaf(c);
        c.inner = true;
        c.count = 0;
      }
    int exponent[3];
    std::array<double, 3> centre{};
    for (int a = 0; a < 3; ++a) {
      float lo = std::numeric_limits<float>::infinity(), hi = -lo;
      for (const Child& c : children) lo = std::min(lo, c.lo[a]), hi = std::max(hi, c.hi[a]);
      boxes.origin[a] = lo;
      exponent[a] = grid_exponent(lo, hi);
      boxes.exponent[a] = static_cast<std::int8_t>(exponent[a]);
      centre[a] = 0.5 * (static_cast<double>(lo) + static_cast<double>(hi));
    }
    const std::array<int, kCompressedWidth> slot_child = assign_slots(children, centre);
    for (u32 slot = 0; slot < kCompressedWidth; ++slot) {
      if (slot_child[slot] < 0) continue;
      const Child& c = children[static_cast<std::size_t>(slot_child[slot])];
      const u32 word = slot / 4, shift = 8 * (slot % 4);
      for (int a = 0; a < 3; ++a) {
        const u32 lo_word = 2 * static_cast<u32>(a) + word, hi_word = 2 * (3 + static_cast<u32>(a)) + word;
        boxes.planes[lo_word] = (boxes.planes[lo_word] & ~(0xffu << shift)) | static_cast<u32>(lower_byte(boxes.origin[a], exponent[a], c.lo[a]))
                                                                                  << shift;
        boxes.planes[hi_word] = (boxes.planes[hi_word] & ~(0xffu << shift)) | static_cast<u32>(upper_byte(boxes.origin[a], exponent[a], c.hi[a]))
                                                                                  << shift;
      }
      node.child[slot] = c.index;
      node.count[slot] = static_cast<std::uint16_t>(c.count);
      if (c.inner) boxes.inner_mask |= static_cast<u8>(1u << slot);
    }
    return node;
  }

  const std::vector<WideBvhNode<float>>& wide_;
  std::vector<CompressedWideNode> out_;
};

}  // namespace

std::vector<CompressedWideNode> compress_wide_bvh(const std::vector<WideBvhNode<float>>& wide) { return Compressor(wide).run(); }

}  // namespace pt
