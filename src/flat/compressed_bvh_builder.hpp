// The compressed wide tree a CUDA build with PT_CUDA_COMPRESSED_BVH walks in float (kernel/compressed_bvh.hpp), made
// from the wide tree host CPUs walk.
#pragma once

#include <vector>

#include "kernel/compressed_bvh.hpp"

namespace pt {

// One compressed node for each wide node, at the same index (so a mesh's wide_root is its root here too), children
// kept: each child's box rounded outwards to its node's byte grid, children placed in slots by their direction from
// the node's centre. A leaf of more than 65,535 primitives (a slot's count is 16 bits) becomes an inner node, appended
// after the others, whose slots share its range and its box.
std::vector<CompressedWideNode> compress_wide_bvh(const std::vector<WideBvhNode<float>>& wide);

}  // namespace pt
