// Cutting a model file's polygons into triangles: ear clipping that looks only at reflex corners, found through a grid.
#include "loading/polygon_cutting.hpp"

#include <algorithm>
#include <cmath>

namespace pt {

PolygonCut cut_polygon(const std::vector<Vec3d>& p, std::vector<std::array<u32, 3>>& out) {
  PolygonCut result;
  const u32 n = static_cast<u32>(p.size());
  const auto fan = [&](u32 first, const std::vector<u32>& next, u32 remaining) {
    for (u32 k = 0, b = next[first]; k + 2 < remaining; ++k, b = next[b]) out.push_back({first, b, next[b]});
  };
  std::vector<u32> next(n), prev(n);
  for (u32 i = 0; i < n; ++i) {
    next[i] = (i + 1) % n;
    prev[i] = (i + n - 1) % n;
  }
  if (n == 3) {
    out.push_back({0, 1, 2});
    return result;
  }
  // Newell's normal: its largest component names the axis to look along.
  Vec3d normal{0, 0, 0};
  for (u32 i = 0; i < n; ++i) {
    const Vec3d& a = p[i];
    const Vec3d& b = p[next[i]];
    normal.x += (a.y - b.y) * (a.z + b.z);
    normal.y += (a.z - b.z) * (a.x + b.x);
    normal.z += (a.x - b.x) * (a.y + b.y);
  }
  const double along[3] = {std::fabs(normal.x), std::fabs(normal.y), std::fabs(normal.z)};
  const int axis = along[0] >= along[1] && along[0] >= along[2] ? 0 : (along[1] >= along[2] ? 1 : 2);
  const double facing = axis == 0 ? normal.x : axis == 1 ? normal.y : normal.z;
  if (!(std::fabs(facing) > 0) || !std::isfinite(facing)) {  // no area: any cut is as good
    fan(0, next, n);
    return result;
  }
  // The other two axes in cyclic order, so that the polygon turns counter-clockwise in them when `facing` > 0.
  std::vector<std::array<double, 2>> q(n);
  for (u32 i = 0; i < n; ++i) {
    const double c[3] = {p[i].x, p[i].y, p[i].z};
    q[i] = {c[(axis + 1) % 3], c[(axis + 2) % 3]};
  }
  const double sign = facing > 0 ? 1.0 : -1.0;
  // > 0 where a, b, c turn the polygon's way (b is a convex corner of a, b, c).
  const auto turn = [&](u32 a, u32 b, u32 c) {
    return sign * ((q[b][0] - q[a][0]) * (q[c][1] - q[a][1]) - (q[b][1] - q[a][1]) * (q[c][0] - q[a][0]));
  };
  if (n == 4 && turn(3, 0, 1) > 0 && turn(0, 1, 2) > 0 && turn(1, 2, 3) > 0 && turn(2, 3, 0) > 0) {
    if (length_squared(p[2] - p[0]) < length_squared(p[3] - p[1]))
      out.insert(out.end(), {{0, 1, 2}, {0, 2, 3}});
    else
      out.insert(out.end(), {{0, 1, 3}, {1, 2, 3}});
    return result;
  }
  const auto same = [&](u32 a, u32 b) { return q[a][0] == q[b][0] && q[a][1] == q[b][1]; };
  // Only a corner that does not turn the polygon's way (a reflex or straight one) can lie inside an ear when no
  // corner lies inside it (for a simple polygon), so the ear test looks only at those, found through a grid over
  // the polygon's bounds: a polygon of n corners is cut in about O(n) steps rather than O(n^2) whatever its shape
  // (a circle of 100,000 corners, a star, a comb), where testing every corner took half a minute.
  std::vector<char> reflex(n);
  u32 reflex_count = 0;
  double lo[2] = {q[0][0], q[0][1]}, hi[2] = {q[0][0], q[0][1]};
  for (u32 i = 0; i < n; ++i) {
    reflex[i] = turn(prev[i], i, next[i]) < 0;
    reflex_count += reflex[i] ? 1 : 0;
    for (int d = 0; d < 2; ++d) lo[d] = std::min(lo[d], q[i][d]), hi[d] = std::max(hi[d], q[i][d]);
  }
  const u32 side = static_cast<u32>(std::clamp(std::sqrt(static_cast<double>(reflex_count)), 1.0, 1024.0));
  const auto cell = [&](double x, int d) {
    const double span = hi[d] - lo[d];
    const double at = span > 0 ? (x - lo[d]) / span * side : 0.0;
    return static_cast<u32>(std::clamp(at, 0.0, static_cast<double>(side - 1)));
  };
  std::vector<std::vector<u32>> grid(static_cast<std::size_t>(side) * side);
  const auto cell_of = [&](u32 i) -> std::vector<u32>& { return grid[static_cast<std::size_t>(cell(q[i][1], 1)) * side + cell(q[i][0], 0)]; };
  // Each reflex corner is filed twice: in its cell, and in a list of all (for ears whose bounds span more cells than
  // there are reflex corners left).
  std::vector<u32> listed, place_in_list(n);
  const auto file = [&](u32 i) {
    cell_of(i).push_back(i);
    place_in_list[i] = static_cast<u32>(listed.size());
    listed.push_back(i);
  };
  const auto unfile = [&](u32 i) {
    std::vector<u32>& entries = cell_of(i);
    const auto it = std::find(entries.begin(), entries.end(), i);
    *it = entries.back();
    entries.pop_back();
    listed[place_in_list[i]] = listed.back();
    place_in_list[listed.back()] = place_in_list[i];
    listed.pop_back();
  };
  for (u32 i = 0; i < n; ++i)
    if (reflex[i]) file(i);
  const auto is_ear = [&](u32 a, u32 b, u32 c) {
    if (turn(a, b, c) <= 0) return false;
    const u32 x0 = cell(std::min({q[a][0], q[b][0], q[c][0]}), 0), x1 = cell(std::max({q[a][0], q[b][0], q[c][0]}), 0);
    const u32 y0 = cell(std::min({q[a][1], q[b][1], q[c][1]}), 1), y1 = cell(std::max({q[a][1], q[b][1], q[c][1]}), 1);
    const auto inside = [&](u32 k) {
      ++result.corner_tests;
      if (k == a || k == b || k == c || same(k, a) || same(k, b) || same(k, c)) return false;  // a corner met twice (an edge to a hole and back)
      return turn(a, b, k) >= 0 && turn(b, c, k) >= 0 && turn(c, a, k) >= 0;
    };
    if (static_cast<std::size_t>(x1 - x0 + 1) * (y1 - y0 + 1) > listed.size()) return std::none_of(listed.begin(), listed.end(), inside);
    for (u32 y = y0; y <= y1; ++y)
      for (u32 x = x0; x <= x1; ++x)
        for (const u32 k : grid[static_cast<std::size_t>(y) * side + x])
          if (inside(k)) return false;
    return true;
  };
  // After a clip a neighbour's turn changes: a reflex corner may become convex (or, in a polygon that is not
  // simple, a convex one reflex). The grid holds exactly the remaining reflex corners.
  const auto update = [&](u32 i) {
    const bool now = turn(prev[i], i, next[i]) < 0;
    if (now && !reflex[i]) file(i);
    if (!now && reflex[i]) unfile(i);
    reflex[i] = now;
  };
  // Which corners to try as an ear's tip: a queue, in passes. Clipping an ear changes whether a corner is an ear only
  // for its two neighbours (O'Rourke, Computational Geometry in C, 1.6), so they alone are queued again; a corner
  // whose neighbour was clipped in this pass waits for the next, so that a pass clips corners apart from each
  // other (a convex polygon is halved pass by pass, not cut as a fan of slivers). A polygon that is not simple can
  // hide ears from that rule: when the queue runs dry, every corner is tried once more before giving up.
  std::vector<u32> queue;
  queue.reserve(2 * static_cast<std::size_t>(n));
  for (u32 i = 0; i < n; i += 2) queue.push_back(i);
  for (u32 i = 1; i < n; i += 2) queue.push_back(i);
  std::vector<char> alive(n, 1), queued(n, 1);
  std::vector<u32> touched(n, 0);  // the pass in which a neighbour was last clipped
  std::size_t head = 0, pass_end = queue.size();
  u32 pass = 1, remaining = n, at = 0;
  bool clipped_since_refill = true;
  while (remaining > 3) {
    if (head == pass_end) {
      ++pass;
      pass_end = queue.size();
    }
    if (head == queue.size()) {
      if (!clipped_since_refill) {
        fan(at, next, remaining);
        result.ears_found = false;
        return result;
      }
      clipped_since_refill = false;
      u32 k = at;
      for (u32 i = 0; i < remaining; ++i, k = next[k])
        if (!queued[k]) queued[k] = 1, queue.push_back(k);
      pass_end = queue.size();
      continue;
    }
    const u32 b = queue[head++];
    if (!alive[b]) continue;
    if (touched[b] == pass) {
      queue.push_back(b);
      continue;
    }
    queued[b] = 0;
    const u32 a = prev[b], c = next[b];
    ++result.ears_tried;
    if (!is_ear(a, b, c)) continue;
    out.push_back({a, b, c});
    next[a] = c;
    prev[c] = a;
    alive[b] = 0;
    if (reflex[b]) unfile(b);
    update(a);
    update(c);
    --remaining;
    at = a;
    clipped_since_refill = true;
    for (const u32 k : {a, c}) {
      touched[k] = pass;
      if (!queued[k]) queued[k] = 1, queue.push_back(k);
    }
  }
  out.push_back({prev[at], at, next[at]});
  return result;
}

}  // namespace pt
