// Cutting a model file's polygons (OBJ faces of any number of corners) into triangles that keep their winding.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "scene/scene.hpp"

namespace pt {

struct PolygonCut {
  bool ears_found = true;        // false for a polygon without an ear (self-intersecting), cut as a fan instead
  std::size_t ears_tried = 0;    // the work done, about linear in the corners: corners tried as an ear's tip,
  std::size_t corner_tests = 0;  // and corners tested for lying inside a candidate ear
};

// Appends to `out` triangles of corner numbers (0 to corners.size() - 1) that cover the polygon with its winding. A
// convex quadrilateral is cut along its shorter diagonal; anything else by ear clipping, in the coordinate plane the
// polygon is seen flattest from, so that concave polygons (and polygons joined to a hole by an edge walked twice) are
// covered exactly.
PolygonCut cut_polygon(const std::vector<Vec3d>& corners, std::vector<std::array<u32, 3>>& out);

}  // namespace pt
