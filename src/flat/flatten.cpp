// Flattening: transforms applied, boxes split into quads, media given their boundary, bounds computed, BVH built,
// and every value converted from the description's double to the kernels' scalar type.
#include "flat/flat_scene.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "flat/bvh_builder.hpp"
#include "flat/number_formats.hpp"
#include "image/image_io.hpp"

namespace pt {

namespace {

// A value a fixed-point format cannot hold; flatten_scene turns it into an InputError naming the scene.
struct DoesNotFit {
  double value;
};

// Conversion to the kernels' scalar type that refuses, rather than saturates, a value out of a fixed format's range.
template <class T>
T scalar(double v) {
  if constexpr (is_fixed_v<T>) {
    if (!(std::abs(v) <= static_cast<double>(largest<T>()))) throw DoesNotFit{v};
  }
  return static_cast<T>(v);
}

template <class T> Vec3<T> to(const Vec3d& v) { return {scalar<T>(v.x), scalar<T>(v.y), scalar<T>(v.z)}; }

template <class T>
Texture<T> to(const Texture<double>& texture) {
  struct Convert {
    Texture<T> operator()(const SolidTexture<double>& t) const { return SolidTexture<T>{to<T>(t.color)}; }
    Texture<T> operator()(const CheckerTexture<double>& t) const {
      return CheckerTexture<T>{to<T>(t.odd), to<T>(t.even), scalar<T>(t.cells_per_unit)};
    }
    Texture<T> operator()(const UvCheckerTexture<double>& t) const {
      return UvCheckerTexture<T>{to<T>(t.odd), to<T>(t.even), scalar<T>(t.columns), scalar<T>(t.rows)};
    }
    Texture<T> operator()(const ImageTexture<double>& t) const {
      return ImageTexture<T>{t.width, t.height, t.offset, scalar<T>(t.repeat)};
    }
    Texture<T> operator()(const NoiseTexture<double>& t) const {
      return NoiseTexture<T>{scalar<T>(t.scale), t.kind, t.turbulence_depth};
    }
  };
  return visit(Convert{}, texture);
}

template <class T>
Material<T> to(const Material<double>& material) {
  struct Convert {
    Material<T> operator()(const Lambertian<double>& m) const { return Lambertian<T>{m.texture}; }
    Material<T> operator()(const Metal<double>& m) const { return Metal<T>{to<T>(m.albedo), scalar<T>(m.fuzz)}; }
    Material<T> operator()(const Dielectric<double>& m) const { return Dielectric<T>{scalar<T>(m.ior), to<T>(m.tint)}; }
    Material<T> operator()(const DiffuseLight<double>& m) const { return DiffuseLight<T>{m.texture}; }
    Material<T> operator()(const Isotropic<double>& m) const { return Isotropic<T>{m.texture}; }
  };
  return visit(Convert{}, material);
}

template <class T>
Primitive<T> to(const Primitive<double>& primitive) {
  struct Convert {
    Shape<T> operator()(const Sphere<double>& s) const { return Sphere<T>{to<T>(s.center), scalar<T>(s.radius)}; }
    Shape<T> operator()(const MovingSphere<double>& s) const {
      return MovingSphere<T>{to<T>(s.center0), scalar<T>(s.radius), to<T>(s.velocity), scalar<T>(s.time0)};
    }
    Shape<T> operator()(const Triangle<double>& t) const { return Triangle<T>{to<T>(t.p0), to<T>(t.edge1), to<T>(t.edge2), t.attributes}; }
    Shape<T> operator()(const Quad<double>& q) const { return Quad<T>{to<T>(q.corner), to<T>(q.normal), to<T>(q.du), to<T>(q.dv)}; }
    Shape<T> operator()(const ConstantMedium<double>& m) const {
      return ConstantMedium<T>{m.first_boundary, m.boundary_count, scalar<T>(m.neg_inv_density)};
    }
  };
  return Primitive<T>{visit(Convert{}, primitive.shape), primitive.material};
}

// The primitive with every length multiplied by s; 1 / density is a length, a quad's dual edges are per length.
Primitive<double> scaled(const Primitive<double>& primitive, double s) {
  struct Scale {
    double s;
    Shape<double> operator()(const Sphere<double>& x) const { return Sphere<double>{x.center * s, x.radius * s}; }
    Shape<double> operator()(const MovingSphere<double>& x) const {
      return MovingSphere<double>{x.center0 * s, x.radius * s, x.velocity * s, x.time0};
    }
    Shape<double> operator()(const Triangle<double>& x) const { return Triangle<double>{x.p0 * s, x.edge1 * s, x.edge2 * s, x.attributes}; }
    Shape<double> operator()(const Quad<double>& x) const { return Quad<double>{x.corner * s, x.normal, x.du / s, x.dv / s}; }
    Shape<double> operator()(const ConstantMedium<double>& x) const {
      return ConstantMedium<double>{x.first_boundary, x.boundary_count, x.neg_inv_density * s};
    }
  };
  return Primitive<double>{visit(Scale{s}, primitive.shape), primitive.material};
}

// Textures that read the world position keep their pattern in place on the scaled scene.
Texture<double> scaled(Texture<double> texture, double s) {
  if (auto* t = std::get_if<CheckerTexture<double>>(&texture)) t->cells_per_unit /= s;
  if (auto* t = std::get_if<NoiseTexture<double>>(&texture)) t->scale /= s;
  return texture;
}

// The largest absolute coordinate of any bounds, the camera and its image plane.
double scene_extent(const std::vector<Aabb>& bounds, const Camera<double>& camera) {
  double extent = 0;
  auto grow = [&](const Vec3d& p) { extent = std::max({extent, std::abs(p.x), std::abs(p.y), std::abs(p.z)}); };
  for (const Aabb& b : bounds)
    if (b.lo.x <= b.hi.x) {
      grow(b.lo);
      grow(b.hi);
    }
  grow(camera.origin);
  grow(camera.lower_left);
  grow(camera.lower_left + camera.horizontal + camera.vertical);
  return extent;
}

// The six faces of a box, outward-facing, moved by the transform.
std::vector<Quad<double>> box_faces(const BoxSettings& box, const RigidTransform& transform) {
  const Vec3d a = box.min, b = box.max;
  const Vec3d dx{b.x - a.x, 0, 0}, dy{0, b.y - a.y, 0}, dz{0, 0, b.z - a.z};
  const std::array<std::array<Vec3d, 3>, 6> faces{{
      {Vec3d{a.x, a.y, b.z}, dx, dy},   // +z
      {Vec3d{b.x, a.y, b.z}, -dz, dy},  // +x
      {Vec3d{b.x, a.y, a.z}, -dx, dy},  // -z
      {Vec3d{a.x, a.y, a.z}, dz, dy},   // -x
      {Vec3d{a.x, b.y, b.z}, dx, -dz},  // +y
      {Vec3d{a.x, a.y, a.z}, dx, dz},   // -y
  }};
  std::vector<Quad<double>> quads;
  for (const auto& f : faces)
    quads.push_back(make_quad(transform.apply_point(f[0]), transform.apply_vector(f[1]), transform.apply_vector(f[2])));
  return quads;
}

Aabb sphere_bounds(const Vec3d& c, double r) {
  Aabb box;
  box.grow(c - Vec3d::splat(r));
  box.grow(c + Vec3d::splat(r));
  return box;
}

Aabb geometry_bounds(const Primitive<double>& p, double shutter_open, double shutter_close) {
  Aabb box;
  if (const auto* s = std::get_if<Sphere<double>>(&p.shape)) return sphere_bounds(s->center, s->radius);
  if (const auto* s = std::get_if<MovingSphere<double>>(&p.shape)) {
    box = sphere_bounds(moving_sphere_center(*s, shutter_open), s->radius);
    box.grow(sphere_bounds(moving_sphere_center(*s, shutter_close), s->radius));
  } else if (const auto* t = std::get_if<Triangle<double>>(&p.shape)) {
    box.grow(t->p0);
    box.grow(t->p0 + t->edge1);
    box.grow(t->p0 + t->edge2);
  } else if (const auto* q = std::get_if<Quad<double>>(&p.shape)) {
    Vec3d u, v;
    quad_edges(*q, u, v);
    box.grow(q->corner);
    box.grow(q->corner + u);
    box.grow(q->corner + v);
    box.grow(q->corner + u + v);
  }
  return box;
}

// Widens a box so that rounding in the kernels' scalar type can never make a ray miss the box of a primitive
// it hits (the BVH must find exactly what brute force finds).
template <class T>
BvhNode<T> padded_node(const BvhNode<double>& n) {
  const Vec3d extent = n.hi - n.lo;
  const double magnitude = std::max(max_component(vmax(vmax(n.lo, -n.lo), vmax(n.hi, -n.hi))), max_component(extent));
  const double pad = 1e-5 * magnitude + 1e-9;
  BvhNode<T> out;
  out.lo = to<T>(n.lo - Vec3d::splat(pad));
  out.hi = to<T>(n.hi + Vec3d::splat(pad));
  out.left_first = n.left_first;
  out.count = n.count;
  return out;
}

// The wide tree, folded from the binary one by dynamic programming over its subtrees: each subtree becomes a leaf
// (its primitives are one contiguous range), a wide node, or is shared out among up to kWideBvhWidth children of
// its wide parent, whichever gives the least expected cost per ray (kWideNodeCost, kWidePrimitiveCost). Opening
// the widest boxes greedily, as before, left most nodes at the bottom of the tree with two children.
template <class T>
class WideBvhBuilder {
 public:
  explicit WideBvhBuilder(const std::vector<BvhNode<double>>& binary) : binary_(binary) {}

  std::vector<WideBvhNode<T>> build() {
    const BvhNode<double>& root = binary_[0];
    if (root.count > 0) {
      const u32 slot = add_node();
      set_child(slot, 0, 0, root.left_first, root.count);
      wide_[slot].leaf_mask = 1;
    } else if (root.lo.x > root.hi.x) {
      add_node();  // no primitives: no child to enter
    } else {
      plan();
      emit(0);
    }
    return std::move(wide_);
  }

 private:
  // How a subtree is best represented as at most `slots` children of a wide node.
  enum class Form : u8 { kLeaf, kNode, kFewerSlots, kShared };
  struct Choice {
    double cost = 0;
    Form form = Form::kLeaf;
    u8 left_slots = 0;  // kShared: slots given to the left subtree, the rest to the right
  };
  using Choices = std::array<Choice, kWideBvhWidth + 1>;  // index: slots, 1 to kWideBvhWidth

  u32 add_node() {
    wide_.push_back(WideBvhNode<T>{});
    return static_cast<u32>(wide_.size() - 1);
  }
  void set_child(u32 slot, u32 lane, u32 binary_index, u32 child, u32 count) {
    const BvhNode<T> box = padded_node<T>(binary_[binary_index]);
    const T planes[6] = {box.lo.x, box.lo.y, box.lo.z, box.hi.x, box.hi.y, box.hi.z};
    for (int p = 0; p < 6; ++p) wide_[slot].bounds[p][lane] = planes[p];
    wide_[slot].child[lane] = child;
    wide_[slot].count[lane] = count;
  }
  static double area(const BvhNode<double>& n) {
    const Vec3d d = n.hi - n.lo;
    return d.x * d.y + d.y * d.z + d.z * d.x;
  }
  bool is_leaf(u32 n) const { return binary_[n].count > 0; }
  u32 left(u32 n) const { return n + 1; }  // depth-first order: the first child follows its parent
  u32 right(u32 n) const { return binary_[n].left_first; }

  // The cheapest split of `slots` children between the two subtrees of interior node n.
  Choice shared(u32 n, u32 slots) const {
    Choice best{std::numeric_limits<double>::infinity(), Form::kShared, 0};
    for (u32 k = 1; k < slots; ++k) {
      const double cost = choices_[left(n)][k].cost + choices_[right(n)][slots - k].cost;
      if (cost < best.cost) best = Choice{cost, Form::kShared, static_cast<u8>(k)};
    }
    return best;
  }

  // Fills choices_ bottom-up (children come after their parent in the binary array), with each subtree's first
  // primitive and primitive count.
  void plan() {
    const std::size_t count = binary_.size();
    choices_.assign(count, Choices{});
    first_.assign(count, 0);
    size_.assign(count, 0);
    for (std::size_t i = count; i-- > 0;) {
      const u32 n = static_cast<u32>(i);
      const double a = area(binary_[n]);
      if (is_leaf(n)) {
        first_[n] = binary_[n].left_first;
        size_[n] = binary_[n].count;
        for (u32 slots = 1; slots <= kWideBvhWidth; ++slots) choices_[n][slots] = Choice{a * size_[n] * kWidePrimitiveCost, Form::kLeaf, 0};
        continue;
      }
      first_[n] = first_[left(n)];
      size_[n] = size_[left(n)] + size_[right(n)];
      Choice one{a * kWideNodeCost + shared(n, kWideBvhWidth).cost, Form::kNode, 0};
      if (size_[n] <= kMaxLeafSize && a * size_[n] * kWidePrimitiveCost <= one.cost) one = Choice{a * size_[n] * kWidePrimitiveCost, Form::kLeaf, 0};
      choices_[n][1] = one;
      for (u32 slots = 2; slots <= kWideBvhWidth; ++slots) {
        const Choice split = shared(n, slots);
        choices_[n][slots] = split.cost < choices_[n][slots - 1].cost ? split : Choice{choices_[n][slots - 1].cost, Form::kFewerSlots, 0};
      }
    }
  }

  // The subtrees that become children of one wide node when subtree n gets `slots` of its slots.
  void gather(u32 n, u32 slots, std::vector<u32>& children) const {
    const Choice& c = choices_[n][slots];
    switch (c.form) {
      case Form::kFewerSlots: return gather(n, slots - 1, children);
      case Form::kShared:
        gather(left(n), c.left_slots, children);
        gather(right(n), slots - c.left_slots, children);
        return;
      default: children.push_back(n);
    }
  }

  // Emits the wide node for binary interior node n; returns its position.
  u32 emit(u32 n) {
    std::vector<u32> children;
    const Choice split = shared(n, kWideBvhWidth);
    gather(left(n), split.left_slots, children);
    gather(right(n), kWideBvhWidth - split.left_slots, children);
    const u32 slot = add_node();
    for (u32 lane = 0; lane < kWideBvhWidth; ++lane) {
      const u32 m = children[lane < children.size() ? lane : 0];
      set_child(slot, lane, m, first_[m], size_[m]);
    }
    for (u32 lane = 0; lane < children.size(); ++lane) {
      const u32 m = children[lane];
      if (choices_[m][1].form == Form::kLeaf) {
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

  const std::vector<BvhNode<double>>& binary_;
  std::vector<Choices> choices_;
  std::vector<u32> first_, size_;
  std::vector<WideBvhNode<T>> wide_;
};

template <class T>
Camera<T> make_camera(const CameraSettings& c, u32 width, u32 height) {
  const double theta = c.vertical_fov * 3.14159265358979323846 / 180.0;
  const double viewport_height = 2.0 * std::tan(theta / 2);
  const double viewport_width = viewport_height * width / height;
  const Vec3d w = normalize(c.look_from - c.look_at);
  const Vec3d u = normalize(cross(c.up, w));
  const Vec3d v = cross(w, u);
  const Vec3d horizontal = c.focus_distance * viewport_width * u;
  const Vec3d vertical = c.focus_distance * viewport_height * v;
  const Vec3d lower_left = c.look_from - horizontal / 2.0 - vertical / 2.0 - c.focus_distance * w;
  const double lens_radius = c.aperture / 2;
  return Camera<T>{to<T>(c.look_from), to<T>(lower_left), to<T>(horizontal), to<T>(vertical),
                   to<T>(u * lens_radius),  to<T>(v * lens_radius),  scalar<T>(c.shutter_open),
                   scalar<T>(c.shutter_close - c.shutter_open)};
}

// Perlin tables from a fixed hash, identical on every platform and compiler.
template <class T>
void make_perlin_tables(FlatScene<T>& flat) {
  auto uniform = [](u64 i) { return static_cast<double>(mix64(i * 0x9e3779b97f4a7c15ULL + 0x5bd1e995u) >> 11) * 0x1p-53; };
  for (u32 i = 0; i < kPerlinPoints; ++i) {
    const Vec3d g = uniform_unit_vector(uniform(2 * i), uniform(2 * i + 1));
    flat.perlin_gradients.push_back(to<T>(g));
  }
  for (u32 axis = 0; axis < 3; ++axis) {
    std::vector<u32> p(kPerlinPoints);
    for (u32 i = 0; i < kPerlinPoints; ++i) p[i] = i;
    for (u32 i = kPerlinPoints - 1; i > 0; --i) {
      const u32 j = static_cast<u32>(mix64(0xabcdefULL + axis * 1000003ULL + i) % (i + 1));
      std::swap(p[i], p[j]);
    }
    flat.perlin_permutations.insert(flat.perlin_permutations.end(), p.begin(), p.end());
  }
}

}  // namespace

template <class T>
FlatScene<T> flatten_scene(const SceneDescription& scene, const RenderSettings& settings, double scale) {
  std::vector<Primitive<double>> primitives, boundaries;
  std::vector<TriangleAttributes<double>> attributes;
  for (const SceneObject& object : scene.objects) {
    const RigidTransform& xf = object.transform;
    if (const auto* s = std::get_if<Sphere<double>>(&object.shape)) {
      primitives.push_back({Sphere<double>{xf.apply_point(s->center), s->radius}, object.material});
    } else if (const auto* s = std::get_if<MovingSphereSettings>(&object.shape)) {
      const Vec3d c0 = xf.apply_point(s->center0), c1 = xf.apply_point(s->center1);
      primitives.push_back({MovingSphere<double>{c0, s->radius, (c1 - c0) / (s->time1 - s->time0), s->time0}, object.material});
    } else if (const auto* t = std::get_if<TriangleSettings>(&object.shape)) {
      const Vec3d p0 = xf.apply_point(t->vertices[0]), p1 = xf.apply_point(t->vertices[1]), p2 = xf.apply_point(t->vertices[2]);
      i32 attribute_index = -1;
      if (t->normals || t->uvs) {
        TriangleAttributes<double> a{};
        if (t->normals) {
          a.has_normals = 1;
          for (int i = 0; i < 3; ++i) a.normal[i] = normalize(xf.apply_vector((*t->normals)[i]));
        }
        if (t->uvs) {
          a.has_uvs = 1;
          for (int i = 0; i < 3; ++i) {
            a.u[i] = (*t->uvs)[i][0];
            a.v[i] = (*t->uvs)[i][1];
          }
        }
        attribute_index = static_cast<i32>(attributes.size());
        attributes.push_back(a);
      }
      primitives.push_back({Triangle<double>{p0, p1 - p0, p2 - p0, attribute_index}, object.material});
    } else if (const auto* q = std::get_if<QuadSettings>(&object.shape)) {
      primitives.push_back({make_quad(xf.apply_point(q->corner), xf.apply_vector(q->u), xf.apply_vector(q->v)), object.material});
    } else if (const auto* b = std::get_if<BoxSettings>(&object.shape)) {
      for (const Quad<double>& face : box_faces(*b, xf)) primitives.push_back({face, object.material});
    } else if (const auto* m = std::get_if<MediumSettings>(&object.shape)) {
      const RigidTransform boundary_xf = m->boundary_transform.then(xf);
      const u32 first = static_cast<u32>(boundaries.size());
      if (const auto* s = std::get_if<Sphere<double>>(&m->boundary))
        boundaries.push_back({Sphere<double>{boundary_xf.apply_point(s->center), s->radius}, object.material});
      else
        for (const Quad<double>& face : box_faces(std::get<BoxSettings>(m->boundary), boundary_xf)) boundaries.push_back({face, object.material});
      primitives.push_back({ConstantMedium<double>{first, static_cast<u32>(boundaries.size()) - first, -1.0 / m->density}, object.material});
    }
  }
  // Media draw from dimension kDimMediumBase + primitive index: keep that inside 32 bits.
  if (primitives.size() >= (1ull << 31) - kDimMediumBase) throw InputError(fmt::format("{}: too many primitives", scene.source));

  const double open = scene.camera.shutter_open, close = scene.camera.shutter_close;
  auto all_bounds = [&] {
    std::vector<Aabb> bounds;
    bounds.reserve(primitives.size());
    for (const Primitive<double>& p : primitives) {
      if (const auto* m = std::get_if<ConstantMedium<double>>(&p.shape)) {
        Aabb box;
        for (u32 i = 0; i < m->boundary_count; ++i) box.grow(geometry_bounds(boundaries[m->first_boundary + i], open, close));
        bounds.push_back(box);
      } else {
        bounds.push_back(geometry_bounds(p, open, close));
      }
    }
    return bounds;
  };
  std::vector<Aabb> bounds = all_bounds();

  // Fixed point: scale all lengths by a power of two (exact in binary) so that squared distances stay in range.
  if (!(scale > 0)) {
    scale = 1;
    if constexpr (is_fixed_v<T>) {
      const double extent = scene_extent(bounds, make_camera<double>(scene.camera, settings.width, settings.height));
      const double fit = std::sqrt(static_cast<double>(largest<T>())) / 2;
      if (extent > fit) scale = std::exp2(std::floor(std::log2(fit / extent)));
    }
  }
  CameraSettings camera = scene.camera;
  std::vector<Texture<double>> textures = scene.textures;
  if (scale != 1) {
    for (Primitive<double>& p : primitives) p = scaled(p, scale);
    for (Primitive<double>& p : boundaries) p = scaled(p, scale);
    for (Texture<double>& t : textures) t = scaled(t, scale);
    camera.look_from = camera.look_from * scale;
    camera.look_at = camera.look_at * scale;
    camera.focus_distance *= scale;
    camera.aperture *= scale;
    bounds = all_bounds();
  }
  const BuiltBvh bvh = build_bvh(bounds);

  FlatScene<T> flat;
  flat.scale = scale;
  try {
  flat.bvh_depth = bvh.depth;
  flat.nodes.reserve(bvh.nodes.size());
  for (const BvhNode<double>& n : bvh.nodes) flat.nodes.push_back(padded_node<T>(n));
  flat.wide_nodes = WideBvhBuilder<T>(bvh.nodes).build();
  flat.primitives.reserve(primitives.size());
  for (u32 index : bvh.order) flat.primitives.push_back(to<T>(primitives[index]));
  for (const Primitive<double>& p : boundaries) flat.boundaries.push_back(to<T>(p));
  for (const TriangleAttributes<double>& a : attributes) {
    TriangleAttributes<T> out{};
    for (int i = 0; i < 3; ++i) {
      out.normal[i] = to<T>(a.normal[i]);
      out.u[i] = scalar<T>(a.u[i]);
      out.v[i] = scalar<T>(a.v[i]);
    }
    out.has_normals = a.has_normals;
    out.has_uvs = a.has_uvs;
    flat.triangle_attributes.push_back(out);
  }
  for (const Material<double>& m : scene.materials) flat.materials.push_back(to<T>(m));
  for (const Texture<double>& t : textures) flat.textures.push_back(to<T>(t));
  flat.texels = scene.texels;
  flat.srgb_decode = srgb_decode_table();
  make_perlin_tables(flat);
  flat.camera = make_camera<T>(camera, settings.width, settings.height);
  flat.background = Background<T>{to<T>(scene.background.horizon), to<T>(scene.background.zenith)};
  flat.params = RenderParams<T>{settings.width, settings.height, settings.max_depth, settings.seed, settings.roulette_depth};
  } catch (const DoesNotFit& e) {
    throw InputError(fmt::format("{}: value {:g} does not fit {} (largest {:g}) after scaling lengths by {:g} (see docs/numerics.md)",
                                 scene.source, e.value, number_format_name<T>(), static_cast<double>(largest<T>()), scale));
  }
  flat.samples_per_pixel = settings.samples_per_pixel;
  return flat;
}

template <class T>
SceneView<T> FlatScene<T>::view() const {
  return place_scene(*this, [](const auto& array, const char*) { return array.data(); });
}

template <class T>
std::size_t FlatScene<T>::bytes() const {
  return nodes.size() * sizeof(nodes[0]) + wide_nodes.size() * sizeof(WideBvhNode<T>) + primitives.size() * sizeof(primitives[0]) + boundaries.size() * sizeof(boundaries[0]) +
         triangle_attributes.size() * sizeof(TriangleAttributes<T>) + materials.size() * sizeof(Material<T>) +
         textures.size() * sizeof(Texture<T>) + texels.size() + srgb_decode.size() * sizeof(float) + perlin_gradients.size() * sizeof(Vec3<T>) +
         perlin_permutations.size() * sizeof(u32);
}

// Written out here rather than through the traversal's intersect_leaf: this is the reference the traversal is checked
// against, so it shares only the primitive tests with it.
template <class T>
bool closest_hit_brute_force(const FlatScene<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit) {
  T closest = largest<T>();
  bool found = false;
  for (u32 i = 0; i < scene.primitives.size(); ++i) {
    Hit<T> candidate;
    if (intersect_primitive(scene.primitives[i], i, context, ray, hit_distance_min<T>(), closest, candidate)) {
      closest = candidate.t;
      hit = candidate;
      hit.primitive = i;
      found = true;
    }
  }
  return found;
}

#define PT_INSTANTIATE_FLAT_SCENE(T)                                                                  \
  template struct FlatScene<T>;                                                                       \
  template FlatScene<T> flatten_scene<T>(const SceneDescription&, const RenderSettings&, double);            \
  template bool closest_hit_brute_force<T>(const FlatScene<T>&, const Ray<T>&, const IntersectContext<T>&, Hit<T>&);
PT_INSTANTIATE_FLAT_SCENE(float)
PT_INSTANTIATE_FLAT_SCENE(double)
#define PT_INSTANTIATE_FIXED_FLAT_SCENE(I, F) \
  using Fixed##I##_##F = Fixed<I, F>;        \
  PT_INSTANTIATE_FLAT_SCENE(Fixed##I##_##F)
PT_FOR_EACH_FIXED_FORMAT(PT_INSTANTIATE_FIXED_FLAT_SCENE)

}  // namespace pt
