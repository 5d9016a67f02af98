// The wide BVH folded from the binary one, for every scalar type the kernels are built for.
#include "flat/wide_bvh_builder.hpp"

#include <array>
#include <limits>

#include "base/scalar_types.hpp"

namespace pt {

namespace {

// The wide tree, folded from the binary one by dynamic programming over its subtrees: each subtree becomes a leaf
// (its primitives are one contiguous range), a wide node, or is shared out among up to kWideBvhWidth children of
// its wide parent, whichever gives the least expected cost per ray (kWideNodeCost, kWidePrimitiveCost). Opening
// the widest boxes greedily, as before, left most nodes at the bottom of the tree with two children.
// The binary nodes' boxes are multiplied by `scale` (a power of two) as they are read.
//
// Memory: 8 bytes a binary node (one byte per number of slots: the choice made), besides the result. The costs of
// a subtree are needed only until its parent is planned; planning goes backwards through the depth-first array,
// so those waiting form a stack no deeper than the tree.
template <class T, class S>
class WideBvhBuilder {
 public:
  WideBvhBuilder(const std::vector<BvhNode<S>>& binary, double scale, const std::vector<bool>& alone_at)
      : binary_(binary), scale_(scale), alone_at_(alone_at) {}

  std::vector<WideBvhNode<T>> build() {
    const BvhNode<S>& root = binary_[0];
    if (root.count > 0) {
      const u32 slot = add_node();
      set_child(slot, 0, 0, root.left_first, root.count);
      wide_[slot].leaf_mask = 1;
    } else if (root.lo.x > root.hi.x) {
      add_node();  // no primitives: no child to enter
    } else {
      plan();
      wide_.reserve(count_nodes(0));
      emit(0);
    }
    return std::move(wide_);
  }

 private:
  // How a subtree is best represented as at most `slots` children of a wide node.
  enum class Form : u8 { kLeaf, kNode, kFewerSlots, kShared };
  // The choice for each number of slots (index slots - 1): the form in the low two bits and above them, for
  // kShared, the slots given to the left subtree (the rest go to the right). For one slot, the bits above hold
  // how the node's kWideBvhWidth children are shared between its subtrees should it become a wide node.
  using Choices = std::array<u8, kWideBvhWidth>;
  static u8 pack(Form form, u32 left_slots) { return static_cast<u8>(static_cast<u32>(form) | left_slots << 2); }
  Form form(u32 n, u32 slots) const { return static_cast<Form>(choices_[n][slots - 1] & 3); }
  u32 left_slots(u32 n, u32 slots) const { return choices_[n][slots - 1] >> 2; }

  // A planned subtree whose parent is not planned yet: its expected cost with each number of slots (1 to
  // kWideBvhWidth) and its primitive count.
  struct Planned {
    u32 node = 0, size = 0;
    std::array<double, kWideBvhWidth + 1> cost{};
    bool alone = false;  // it holds a primitive that keeps a leaf of its own: it cannot become one leaf unless it is one
  };

  u32 add_node() {
    wide_.push_back(WideBvhNode<T>{});
    return static_cast<u32>(wide_.size() - 1);
  }
  void set_child(u32 slot, u32 lane, u32 binary_index, u32 child, u32 count) {
    const BvhNode<T> box = padded_node<T>(binary_[binary_index], scale_);
    const T planes[6] = {box.lo.x, box.lo.y, box.lo.z, box.hi.x, box.hi.y, box.hi.z};
    for (int p = 0; p < 6; ++p) wide_[slot].bounds[p][lane] = planes[p];
    wide_[slot].child[lane] = child;
    wide_[slot].count[lane] = count;
  }
  double area(u32 n) const {
    const Aabb box = scaled_box(binary_[n], scale_);
    const Vec3d d = box.hi - box.lo;
    return d.x * d.y + d.y * d.z + d.z * d.x;
  }
  bool is_leaf(u32 n) const { return binary_[n].count > 0; }
  u32 left(u32 n) const { return n + 1; }  // depth-first order: the first child follows its parent
  u32 right(u32 n) const { return binary_[n].left_first; }
  // A subtree's primitives are one range: from its leftmost leaf's first to its rightmost leaf's last.
  u32 first(u32 n) const {
    while (!is_leaf(n)) n = left(n);
    return binary_[n].left_first;
  }
  u32 size(u32 n) const {
    u32 last = n;
    while (!is_leaf(last)) last = right(last);
    return binary_[last].left_first + binary_[last].count - first(n);
  }

  // The cheapest split of `slots` children between the two subtrees of an interior node: its cost and the slots of
  // the left subtree (0 where there is none, for one slot).
  static std::pair<double, u32> shared(const Planned& left, const Planned& right, u32 slots) {
    std::pair<double, u32> best{std::numeric_limits<double>::infinity(), 0};
    for (u32 k = 1; k < slots; ++k) {
      const double cost = left.cost[k] + right.cost[slots - k];
      if (cost < best.first) best = {cost, k};
    }
    return best;
  }

  // Fills choices_ bottom-up: backwards through the depth-first array, where a node's subtrees come after it, the
  // left one planned last.
  void plan() {
    const std::size_t count = binary_.size();
    choices_.assign(count, Choices{});  // zero: kLeaf for every number of slots
    std::vector<Planned> waiting;
    waiting.reserve(kBvhMaxDepth + 2);
    for (std::size_t i = count; i-- > 0;) {
      const u32 n = static_cast<u32>(i);
      const double a = area(n);
      Planned p{n, 0, {}};
      if (is_leaf(n)) {
        p.size = binary_[n].count;
        for (u32 i = 0; i < p.size && !alone_at_.empty(); ++i) p.alone = p.alone || alone_at_[binary_[n].left_first + i];
        for (u32 slots = 1; slots <= kWideBvhWidth; ++slots) p.cost[slots] = a * p.size * kWidePrimitiveCost;
        waiting.push_back(p);
        continue;
      }
      if (waiting.size() < 2 || waiting.back().node != left(n) || waiting[waiting.size() - 2].node != right(n))
        throw std::logic_error("the binary BVH is not in depth-first order");
      const Planned l = waiting.back();
      waiting.pop_back();
      const Planned r = waiting.back();
      waiting.pop_back();
      p.size = l.size + r.size;
      p.alone = l.alone || r.alone;
      const auto [node_cost, node_left_slots] = shared(l, r, kWideBvhWidth);
      p.cost[1] = a * kWideNodeCost + node_cost;
      Form one = Form::kNode;
      if (p.size <= kMaxLeafSize && !p.alone && a * p.size * kWidePrimitiveCost <= p.cost[1]) {
        p.cost[1] = a * p.size * kWidePrimitiveCost;
        one = Form::kLeaf;
      }
      choices_[n][0] = pack(one, node_left_slots);
      for (u32 slots = 2; slots <= kWideBvhWidth; ++slots) {
        const auto [split_cost, k] = shared(l, r, slots);
        if (split_cost < p.cost[slots - 1]) {
          p.cost[slots] = split_cost;
          choices_[n][slots - 1] = pack(Form::kShared, k);
        } else {
          p.cost[slots] = p.cost[slots - 1];
          choices_[n][slots - 1] = pack(Form::kFewerSlots, 0);
        }
      }
      waiting.push_back(p);
    }
  }

  // The subtrees that become children of one wide node when subtree n gets `slots` of its slots.
  void gather(u32 n, u32 slots, std::vector<u32>& children) const {
    switch (form(n, slots)) {
      case Form::kFewerSlots: return gather(n, slots - 1, children);
      case Form::kShared: {
        const u32 k = left_slots(n, slots);
        gather(left(n), k, children);
        gather(right(n), slots - k, children);
        return;
      }
      default: children.push_back(n);
    }
  }
  // The children of the wide node made for binary interior node n.
  std::vector<u32> wide_children(u32 n) const {
    std::vector<u32> children;
    const u32 k = left_slots(n, 1);
    gather(left(n), k, children);
    gather(right(n), kWideBvhWidth - k, children);
    return children;
  }

  // How many wide nodes emit(n) makes (so that the result is allocated once).
  std::size_t count_nodes(u32 n) const {
    std::size_t total = 1;
    for (const u32 m : wide_children(n))
      if (form(m, 1) != Form::kLeaf) total += count_nodes(m);
    return total;
  }

  // Emits the wide node for binary interior node n; returns its position.
  u32 emit(u32 n) {
    const std::vector<u32> children = wide_children(n);
    const u32 slot = add_node();
    for (u32 lane = 0; lane < kWideBvhWidth; ++lane) {
      const u32 m = children[lane < children.size() ? lane : 0];
      set_child(slot, lane, m, first(m), size(m));
    }
    for (u32 lane = 0; lane < children.size(); ++lane) {
      const u32 m = children[lane];
      if (form(m, 1) == Form::kLeaf) {
        wide_[slot].leaf_mask |= 1u << lane;
        continue;
      }
      wide_[slot].inner_mask |= 1u << lane;
      wide_[slot].count[lane] = 0;
      const u32 child = emit(m);
      wide_[slot].child[lane] = child;
    }
    return slot;
  }

  const std::vector<BvhNode<S>>& binary_;
  double scale_;
  const std::vector<bool>& alone_at_;
  std::vector<Choices> choices_;
  std::vector<WideBvhNode<T>> wide_;
};

}  // namespace

template <class T, class S>
std::vector<WideBvhNode<T>> build_wide_bvh(const std::vector<BvhNode<S>>& binary, double scale, const std::vector<bool>& alone_at) {
  return WideBvhBuilder<T, S>(binary, scale, alone_at).build();
}

#define PT_INSTANTIATE_WIDE_BVH(...)                                                                                             \
  template std::vector<WideBvhNode<__VA_ARGS__>> build_wide_bvh<__VA_ARGS__, float>(const std::vector<BvhNode<float>>&, double,    \
                                                                                   const std::vector<bool>&);                       \
  template std::vector<WideBvhNode<__VA_ARGS__>> build_wide_bvh<__VA_ARGS__, double>(const std::vector<BvhNode<double>>&, double,  \
                                                                                    const std::vector<bool>&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_WIDE_BVH)

}  // namespace pt
