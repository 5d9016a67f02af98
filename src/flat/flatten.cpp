// Flattening: transforms applied, boxes split into quads, media given their boundary, bounds computed, BVH built,
// and every value converted from the description's double to the kernels' scalar type.
#include "flat/flat_scene.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <utility>
#include <variant>

#include <fmt/format.h>

#include "flat/bvh_builder.hpp"
#include "base/free_memory.hpp"
#include "flat/environment.hpp"
#include "base/number_formats.hpp"
#include "image/image_io.hpp"
#include "scene/mesh.hpp"

namespace pt {

namespace {

// ---- Supported ranges ----
//
// Every value the kernels get passes through Fit below, which refuses, with one InputError naming the file, line,
// column and JSON path where it was written, a value the scalar type cannot hold or that the kernels' arithmetic
// would overflow. What a value is decides its range:
enum class Quantity {
  kLength,         // coordinates and lengths: positions, radii, edges, velocities, 1 / density, the camera's
  kTriangleEdge,   // a triangle's edges, a length raised to the fourth power (see below)
  kInverseLength,  // per unit length: a quad's dual edges, checker frequencies, noise scales
  kColour,         // colours and emission (radiance)
  kPlain,          // without unit: times, indices of refraction, fuzz, texture coordinates and repeats
};

// Float and double. The scene being finite (the parser refuses the rest) is not enough: the kernels raise lengths to
// powers and multiply radiance along a path, and a result past the largest value (below 2^E: 2^128 for float,
// 2^1024 for double) becomes infinite, so the object silently vanishes or every sample is dropped as non-finite.
// With every stored length and coordinate at most L, every point the kernels compute lies within a few L (a quad's
// far corner, corner + u + v, within 3 L; a ray's origin, a hit point or look_from plus the lens, as much), and:
//   - the BVH slab test, bound * (1 / d) - origin * (1 / d), where slab_reciprocal lets 1 / d reach 1e20 (2^66.5),
//     forms products up to 3 L 2^66.5 and their difference, up to 6 L 2^66.5;
//   - the sphere test, radius * radius - length_squared(perpendicular), squares distances of up to 4 L per axis:
//     up to 48 L^2.
// L = 2^(E/2 - 8) keeps all of these at least 7 times below the largest value: float 2^56 (about 7.2e16), double
// 2^504 (about 5.2e151).
// Triangles go further. Their normal normalises cross(edge1, edge2), whose squared length is a fourth power of the
// edges, up to 12 T^4 for edges at most T; their distance, dot(edge2, cross(origin - p0, edge1)), reaches 24 L T^2.
// T = 2^(E/4 - 2) keeps 12 T^4 a factor 21 below the largest value, and 24 L T^2 a factor 2^7: float 2^30 (about
// 1.07e9), double 2^254.
// A sample's radiance is a sum over up to kMaxDepth = 10000 (< 2^14) bounces of an emission times the throughput,
// a product of the colours met; with emission and throughput at most R, R^2 2^14 must stay below 2^E:
// R = 2^floor((E - 15) / 2), float 2^56, double 2^504. (Colours are albedos, at most 1 in a physical scene, so the
// throughput of a long path stays within R.)
// Other values need only fit the type. Fixed point saturates instead of overflowing, and flatten_scene scales lengths
// by a power of two so that squared distances fit; there every value, after that scaling, must fit the format.
template <class T>
double supported_limit(Quantity q) {
  if constexpr (is_fixed_v<T>) {
    return static_cast<double>(largest<T>());
  } else {
    constexpr int exponent = std::numeric_limits<T>::max_exponent;  // E: the largest value lies below 2^E
    if (q == Quantity::kLength) return std::ldexp(1.0, exponent / 2 - 8);
    if (q == Quantity::kTriangleEdge) return std::ldexp(1.0, exponent / 4 - 2);
    if (q == Quantity::kColour) return std::ldexp(1.0, (exponent - 15) / 2);
    return static_cast<double>(largest<T>());
  }
}

const char* quantity_name(Quantity q) {
  switch (q) {
    case Quantity::kLength: return "lengths and coordinates";
    case Quantity::kTriangleEdge: return "triangle edges";
    case Quantity::kColour: return "colours and emission";
    default: return "values";
  }
}

// Where a pointer's components are: "/center" -> "/center/0".
std::string component(const std::string& pointer, int i) { return pointer + "/" + std::to_string(i); }

// Conversion to the kernels' scalar type, refusing what does not fit (see supported_limit). Lengths arrive already
// multiplied by the scene's scale; messages show them as written, and the scaled value.
template <class T>
class Fit {
 public:
  Fit(const SceneDescription& scene, double scale) : scene_(scene), scale_(scale) {}

  // `pointer`: the JSON path where the value was written; `note`: what the value is, where it is not that written
  // value itself (a position after a transform, 1 / density, ...).
  T operator()(double value, Quantity q, const std::string& pointer, const std::string& note = "") const {
    if (!(std::abs(value) <= supported_limit<T>(q))) refuse(value, q, pointer, note);
    return static_cast<T>(value);
  }
  // A vector: as written (no note), each component is named by its own path, /0, /1 or /2.
  Vec3<T> operator()(const Vec3d& v, Quantity q, const std::string& pointer, const std::string& note = "") const {
    auto one = [&](double x, int i) { return (*this)(x, q, note.empty() ? component(pointer, i) : pointer, note); };
    return {one(v.x, 0), one(v.y, 1), one(v.z, 2)};
  }

  // A texture's or a material's JSON path, or a description where the scene was made in code.
  std::string texture(u32 i) const { return i < scene_.written.textures.size() ? scene_.written.textures[i] : fmt::format("(texture {})", i); }
  std::string material(u32 i) const { return i < scene_.written.materials.size() ? scene_.written.materials[i] : fmt::format("(material {})", i); }
  double scale() const { return scale_; }

 private:
  [[noreturn]] void refuse(double value, Quantity q, const std::string& pointer, const std::string& note) const {
    const std::string type = number_format_name<T>();
    const double limit = supported_limit<T>(q);
    const std::string what = note.empty() ? "" : " (" + note + ")";
    const bool length = q == Quantity::kLength || q == Quantity::kTriangleEdge;
    const bool scaled = scale_ != 1 && (length || q == Quantity::kInverseLength);
    const double written = !scaled ? value : length ? value / scale_ : value * scale_;
    const std::string after = scaled ? fmt::format(", {:g} after scaling lengths by {:g},", value, scale_) : "";
    std::string reason;
    if constexpr (is_fixed_v<T>)
      reason = fmt::format("{:g}{}{} does not fit {} (|x| <= {:g}; see docs/numerics.md)", written, what, after, type, limit);
    else if (q != Quantity::kInverseLength && q != Quantity::kPlain)
      reason = fmt::format("{:g}{}{} is beyond {}'s supported range for {} (|x| <= {:.3g}; see docs/scene-format.md)", written, what, after, type,
                           quantity_name(q), limit);
    else
      reason = fmt::format("{:g}{}{} is beyond {}'s range (|x| <= {:.3g})", written, what, after, type, limit);
    throw InputError(fmt::format("{}: {}: {}", source_position(scene_, pointer), pointer, reason));
  }

  const SceneDescription& scene_;
  double scale_;
};

// The environment image: its texels times the strength, which must fit the type as any colour (the brightest is
// checked: for fixed point this refuses most HDR images, docs/environment-lighting.md), its distribution, and the
// rotation into the image's frame (the transpose of the map's).
template <class T>
void flatten_environment(const Fit<T>& fit, const SceneDescription& scene, FlatScene<T>& flat) {
  const EnvironmentSettings& environment = *scene.environment;
  const std::string& pointer = scene.written.environment;
  flat.environment_rgb.resize(environment.rgb.size());
  float brightest = 0;
  for (std::size_t i = 0; i < environment.rgb.size(); ++i) {
    const double value = static_cast<double>(environment.rgb[i]) * environment.strength;
    flat.environment_rgb[i] = static_cast<float>(value);
    brightest = std::max(brightest, flat.environment_rgb[i]);
    // Stored in float whatever the scalar type (kernel/background.hpp, EnvironmentArrays).
    if (!std::isfinite(flat.environment_rgb[i]))
      throw InputError(fmt::format("{}: {}: a texel times the strength, {:g}, exceeds the largest float ({:g}), in which environment images are kept",
                                   source_position(scene, pointer), pointer, value, static_cast<double>(std::numeric_limits<float>::max())));
  }
  fit(brightest, Quantity::kColour, pointer, "the brightest texel times the strength");
  EnvironmentDistribution distribution = environment_distribution(flat.environment_rgb, environment.width, environment.height);
  flat.environment_density = std::move(distribution.density);
  flat.environment_row_cdf = std::move(distribution.row_cdf);
  flat.environment_column_cdfs = std::move(distribution.column_cdfs);
  EnvironmentMap<T>& map = flat.background.environment;
  map.width = environment.width;
  map.height = environment.height;
  for (int i = 0; i < 3; ++i)
    map.to_map.rows[i] = Vec3<T>{static_cast<T>(environment.rotation.rotation[0][i]), static_cast<T>(environment.rotation.rotation[1][i]),
                                 static_cast<T>(environment.rotation.rotation[2][i])};
}

// A value of the BVH or of a fixed table: derived from values Fit has passed (bounds within a few L, unit vectors),
// so it fits; should it not, flatten_scene turns this into an InputError naming the scene.
struct DoesNotFit {
  double value;
};

template <class T>
T scalar(double v) {
  if constexpr (is_fixed_v<T>) {
    if (!(std::abs(v) <= static_cast<double>(largest<T>()))) throw DoesNotFit{v};
  }
  return static_cast<T>(v);
}

template <class T> Vec3<T> to(const Vec3d& v) { return {scalar<T>(v.x), scalar<T>(v.y), scalar<T>(v.z)}; }

template <class T>
Texture<T> fit_texture(const Fit<T>& fit, const Texture<double>& texture, const std::string& at) {
  struct Convert {
    const Fit<T>& fit;
    const std::string& at;  // a solid texture's colour array, or the texture object
    Texture<T> operator()(const SolidTexture<double>& t) const { return SolidTexture<T>{fit(t.color, Quantity::kColour, at)}; }
    Texture<T> operator()(const CheckerTexture<double>& t) const {
      return CheckerTexture<T>{fit(t.odd, Quantity::kColour, at + "/odd"), fit(t.even, Quantity::kColour, at + "/even"),
                               fit(t.cells_per_unit, Quantity::kInverseLength, at + "/frequency", "cells per unit length, frequency / pi")};
    }
    Texture<T> operator()(const UvCheckerTexture<double>& t) const {
      return UvCheckerTexture<T>{fit(t.odd, Quantity::kColour, at + "/odd"), fit(t.even, Quantity::kColour, at + "/even"),
                                 fit(t.columns, Quantity::kPlain, at + "/columns"), fit(t.rows, Quantity::kPlain, at + "/rows")};
    }
    Texture<T> operator()(const ImageTexture<double>& t) const {
      ImageTexture<T> out{t.width, t.height, t.offset, fit(t.repeat, Quantity::kPlain, at + "/repeat"), {}};
      out.factor = fit(t.factor, Quantity::kColour, at, "the colour factor");
      out.linear = t.linear;
      return out;
    }
    Texture<T> operator()(const NoiseTexture<double>& t) const {
      return NoiseTexture<T>{fit(t.scale, Quantity::kInverseLength, at + "/scale"), t.kind, t.turbulence_depth,
                             fit(t.unscale, Quantity::kPlain, at, "1 / the scale of lengths, which the marble's turbulence undoes")};
    }
  };
  return visit(Convert{fit, at}, texture);
}

template <class T>
Material<T> fit_material(const Fit<T>& fit, const Material<double>& material, const std::string& at) {
  struct Convert {
    const Fit<T>& fit;
    const std::string& at;
    Material<T> operator()(const Lambertian<double>& m) const { return Lambertian<T>{m.texture}; }
    Material<T> operator()(const Metal<double>& m) const {
      return Metal<T>{fit(m.albedo, Quantity::kColour, at + "/albedo"), fit(m.fuzz, Quantity::kPlain, at + "/fuzz")};
    }
    Material<T> operator()(const Dielectric<double>& m) const {
      return Dielectric<T>{fit(m.ior, Quantity::kPlain, at + "/ior"), fit(m.tint, Quantity::kColour, at + "/tint")};
    }
    Material<T> operator()(const DiffuseLight<double>& m) const { return DiffuseLight<T>{m.texture}; }
    Material<T> operator()(const Isotropic<double>& m) const { return Isotropic<T>{m.texture}; }
    Material<T> operator()(const MetallicRoughness<double>& m) const {
      return MetallicRoughness<T>{m.base_color, m.metallic_roughness, m.normal_map, fit(m.normal_scale, Quantity::kPlain, at + "/normal_scale")};
    }
  };
  return visit(Convert{fit, at}, material);
}

// Where a primitive was written: its object, or a medium's boundary. Kept small (a scene may have millions of
// primitives); the JSON path and a box as written are looked up when the primitive is converted.
struct PrimitiveOrigin {
  u32 object = 0;
  bool boundary = false;  // the boundary of the object's medium
  bool moved = false;     // a transform moved it: its positions are not the ones written
  bool box = false;       // one of the six faces of a box

  std::string pointer() const { return "/objects/" + std::to_string(object) + (boundary ? "/boundary" : ""); }
  // The box as written, for a face of one.
  std::optional<BoxSettings> written_box(const SceneDescription& scene) const {
    if (!box) return std::nullopt;
    const SceneObject o = scene.objects[object];
    if (boundary) return std::get<BoxSettings>(std::get<MediumSettings>(o.shape).boundary);
    return std::get<BoxSettings>(o.shape);
  }
};

// The primitive in the kernels' type. Besides what is stored, the points and edges the kernels derive from it are
// checked as lengths: a quad's edges u and v, a triangle's other vertices, a moving sphere's centre over the shutter
// interval [open, close].
template <class T>
Primitive<T> fit_primitive(const Fit<T>& fit, const SceneDescription& scene, const Primitive<double>& primitive, const PrimitiveOrigin& written,
                           double open, double close) {
  struct Origin {
    std::string pointer;
    bool moved;
    std::optional<BoxSettings> box;
  };
  struct Convert {
    const Fit<T>& fit;
    const Origin& origin;
    double open, close;

    std::string key(const char* name) const { return origin.pointer + name; }
    // A position as written, or after the object's transform.
    Vec3<T> position(const Vec3d& p, const char* name) const {
      return fit(p, Quantity::kLength, key(name), origin.moved ? "after the object's transform" : "");
    }
    Shape<T> operator()(const Sphere<double>& s) const {
      return Sphere<T>{position(s.center, "/center"), fit(s.radius, Quantity::kLength, key("/radius"))};
    }
    Shape<T> operator()(const MovingSphere<double>& s) const {
      const MovingSphere<T> out{position(s.center0, "/center0"), fit(s.radius, Quantity::kLength, key("/radius")),
                                fit(s.velocity, Quantity::kLength, key("/center1"), "the velocity, (center1 - center0) / (time1 - time0)"),
                                fit(s.time0, Quantity::kPlain, key("/time0"))};
      for (const double time : {open, close})
        fit(moving_sphere_center(s, time), Quantity::kLength, key("/center1"), fmt::format("the centre at the shutter's time {:g}", time));
      return out;
    }
    Shape<T> operator()(const Triangle<double>& t) const {
      position(t.p0 + t.edge1, "/vertices/1");
      position(t.p0 + t.edge2, "/vertices/2");
      const Triangle<T> out{position(t.p0, "/vertices/0"), fit(t.edge1, Quantity::kTriangleEdge, key("/vertices/1"), "the edge from vertex 0"),
                            fit(t.edge2, Quantity::kTriangleEdge, key("/vertices/2"), "the edge from vertex 0"), t.attributes};
      return out;
    }
    Shape<T> operator()(const Quad<double>& q) const {
      Vec3d u, v;
      quad_edges(q, u, v);
      // The dual edges times the type's extents (Quad): sizes of 1 / length where the extent is 1, else near 1.
      const double eu = ScalarTraits<T>::quad_extent(length(u)), ev = ScalarTraits<T>::quad_extent(length(v));
      const Quantity dual = eu == 1 && ev == 1 ? Quantity::kInverseLength : Quantity::kPlain;
      const std::string stored = eu == 1 && ev == 1 ? "1 / an edge's length" : "an edge's dual vector times a power of two near its length";
      const T u_extent = fit(eu, Quantity::kLength, origin.pointer, "a power of two near an edge's length"),
              v_extent = fit(ev, Quantity::kLength, origin.pointer, "a power of two near an edge's length");
      if (origin.box) {
        if (!origin.moved) {  // name the values as written, where they are the ones the faces are made of
          fit(origin.box->min * fit.scale(), Quantity::kLength, key("/min"));
          fit(origin.box->max * fit.scale(), Quantity::kLength, key("/max"));
        }
        const std::string where = origin.moved ? ", after the object's transform" : "";
        const Quad<T> out{fit(q.corner, Quantity::kLength, origin.pointer, "a corner of the box" + where), fit(q.normal, Quantity::kPlain, origin.pointer, "a face's normal"),
                          fit(q.du * eu, dual, origin.pointer, stored + ", as a face stores it"), fit(q.dv * ev, dual, origin.pointer, stored + ", as a face stores it"),
                          u_extent, v_extent};
        fit(u, Quantity::kLength, origin.pointer, "an edge of the box, max - min" + where);
        fit(v, Quantity::kLength, origin.pointer, "an edge of the box, max - min" + where);
        fit(q.corner + u + v, Quantity::kLength, origin.pointer, "a corner of the box" + where);
        return out;
      }
      const std::string turned = origin.moved ? "after the object's transform" : "";
      const std::string stored_u = eu == 1 ? "1 / the length of u" : "u's dual vector times a power of two near its length";
      const std::string stored_v = ev == 1 ? "1 / the length of v" : "v's dual vector times a power of two near its length";
      const Quad<T> out{position(q.corner, "/corner"), fit(q.normal, Quantity::kPlain, origin.pointer, "the normal"),
                        fit(q.du * eu, eu == 1 ? Quantity::kInverseLength : Quantity::kPlain, key("/u"), stored_u + ", as the quad stores it"),
                        fit(q.dv * ev, ev == 1 ? Quantity::kInverseLength : Quantity::kPlain, key("/v"), stored_v + ", as the quad stores it"),
                        u_extent, v_extent};
      fit(u, Quantity::kLength, key("/u"), turned);
      fit(v, Quantity::kLength, key("/v"), turned);
      return out;
    }
    Shape<T> operator()(const ConstantMedium<double>& m) const {
      fit(-m.neg_inv_density, Quantity::kLength, key("/density"), "1 / density, the mean free path");
      return ConstantMedium<T>{m.first_boundary, m.boundary_count, static_cast<T>(m.neg_inv_density)};
    }
    Shape<T> operator()(const MeshInstance<double>& m) const { return MeshInstance<T>{m.mesh, m.transform}; }  // checked with the meshes
  };
  const Origin origin{written.pointer(), written.moved, written.written_box(scene)};
  return Primitive<T>{visit(Convert{fit, origin, open, close}, primitive.shape), primitive.material};
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
    Shape<double> operator()(const Quad<double>& x) const { return Quad<double>{x.corner * s, x.normal, x.du / s, x.dv / s, x.u_extent, x.v_extent}; }
    Shape<double> operator()(const ConstantMedium<double>& x) const {
      return ConstantMedium<double>{x.first_boundary, x.boundary_count, x.neg_inv_density * s};
    }
    Shape<double> operator()(const MeshInstance<double>& x) const { return x; }  // its mesh and transform are scaled apart
  };
  return Primitive<double>{visit(Scale{s}, primitive.shape), primitive.material};
}

// Textures that read the world position keep their pattern in place on the scaled scene.
Texture<double> scaled(Texture<double> texture, double s) {
  if (auto* t = std::get_if<CheckerTexture<double>>(&texture)) t->cells_per_unit /= s;
  if (auto* t = std::get_if<NoiseTexture<double>>(&texture)) t->scale /= s, t->unscale /= s;
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

// A node's box in double, its corners multiplied by `scale` (exact: a power of two).
template <class S>
Aabb scaled_box(const BvhNode<S>& n, double scale) {
  const Vec3d lo{n.lo.x, n.lo.y, n.lo.z}, hi{n.hi.x, n.hi.y, n.hi.z};
  return scale == 1 ? Aabb{lo, hi} : Aabb{lo * scale, hi * scale};
}

// Widens a box so that rounding in the kernels' scalar type can never make a ray miss the box of a primitive
// it hits (the BVH must find exactly what brute force finds). The box is the node's multiplied by `scale`.
template <class T, class S>
BvhNode<T> padded_node(const BvhNode<S>& node, double scale = 1) {
  const Aabb n = scaled_box(node, scale);
  const Vec3d extent = n.hi - n.lo;
  const double magnitude = std::max(max_component(vmax(vmax(n.lo, -n.lo), vmax(n.hi, -n.hi))), max_component(extent));
  const double pad = 1e-5 * magnitude + 1e-9;
  BvhNode<T> out;
  out.lo = to<T>(n.lo - Vec3d::splat(pad));
  out.hi = to<T>(n.hi + Vec3d::splat(pad));
  out.left_first = node.left_first;
  out.count = node.count;
  return out;
}

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
  explicit WideBvhBuilder(const std::vector<BvhNode<S>>& binary, double scale = 1) : binary_(binary), scale_(scale) {}

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
      const auto [node_cost, node_left_slots] = shared(l, r, kWideBvhWidth);
      p.cost[1] = a * kWideNodeCost + node_cost;
      Form one = Form::kNode;
      if (p.size <= kMaxLeafSize && a * p.size * kWidePrimitiveCost <= p.cost[1]) {
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
  std::vector<Choices> choices_;
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
  const double focus = c.focus_distance > 0 ? c.focus_distance : length(c.look_at - c.look_from);  // 0: at look_at
  const Vec3d horizontal = focus * viewport_width * u;
  const Vec3d vertical = focus * viewport_height * v;
  const Vec3d lower_left = c.look_from - horizontal / 2.0 - vertical / 2.0 - focus * w;
  const double lens_radius = c.aperture / 2;
  return Camera<T>{to<T>(c.look_from), to<T>(lower_left), to<T>(horizontal), to<T>(vertical),
                   to<T>(u * lens_radius),  to<T>(v * lens_radius),  scalar<T>(c.shutter_open),
                   scalar<T>(c.shutter_close - c.shutter_open)};
}

// The camera in the kernels' type, its settings checked first (they are lengths even where not stored as such).
template <class T>
Camera<T> fit_camera(const Fit<T>& fit, const CameraSettings& c, u32 width, u32 height) {
  fit(c.look_from, Quantity::kLength, "/camera/look_from");
  fit(c.look_at, Quantity::kLength, "/camera/look_at");
  fit(c.focus_distance, Quantity::kLength, "/camera", "the focus distance, focus_distance or |look_at - look_from|");
  fit(c.aperture, Quantity::kLength, "/camera/aperture");
  const Camera<double> d = make_camera<double>(c, width, height);
  const std::string plane = " of the image on the focus plane (from vertical_fov, the image's shape and the focus distance)";
  return Camera<T>{fit(d.origin, Quantity::kLength, "/camera/look_from"),
                   fit(d.lower_left, Quantity::kLength, "/camera", "the lower-left corner" + plane),
                   fit(d.horizontal, Quantity::kLength, "/camera", "the width" + plane),
                   fit(d.vertical, Quantity::kLength, "/camera", "the height" + plane),
                   fit(d.lens_u, Quantity::kLength, "/camera/aperture", "the lens radius"),
                   fit(d.lens_v, Quantity::kLength, "/camera/aperture", "the lens radius"),
                   fit(d.time0, Quantity::kPlain, "/camera/shutter/0"),
                   fit(d.time_span, Quantity::kPlain, "/camera/shutter", "the time the shutter is open")};
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

// ---- Meshes ----
//
// Each placement of a model file's mesh becomes an instance primitive. A mesh placed once is stored in world space
// (its instance has no transform, so rays are not transformed for it); a mesh placed more often is stored once in its
// own space with one BVH, and each instance carries the affine map into and out of that space.

// A placement met while reading the objects; `primitive` is its instance's index in the primitive list.
struct MeshPlacementUse {
  u32 file, mesh;
  AffineTransform transform;  // mesh space to world
  u32 object;
};

// A mesh as the kernels will store it, before conversion to their scalar type: triangles (local vertex indices,
// scene materials) in BVH order and its BVH over them. Vertices, normals and texture coordinates are not copied:
// they are read from the file's mesh, mapped by `placed`, when converted.
struct MeshBuild {
  u32 object;        // the first object placing it, for messages
  std::string name;  // the file's name for it
  const TriangleMesh* source = nullptr;
  AffineTransform placed;  // mesh space to the space the mesh is stored in (the identity for a shared mesh)
  bool identity = true;    // placed is the identity
  bool has_normals = false, has_uvs = false;
  bool has_tangents = false;  // the file's vertex tangents, kept where a triangle's material has a normal map
  double scale = 1;  // flatten_scene's scale, applied to lengths as they are converted
  std::vector<MeshTriangle> triangles;
  // Float boxes where the mesh's coordinates fit float (half the memory of double; exact corners for float
  // vertices, rounded outward otherwise), double boxes beyond.
  std::variant<BuiltBvh<float>, BuiltBvh<double>> bvh;

  Vec3d position(u32 v) const { return identity ? source->positions[v] : placed.apply_point(source->positions[v]); }
  // A tangent is a vector along the surface: it goes by the map itself (normals by its inverse transpose).
  Vec3d tangent(u32 v) const {
    const std::array<double, 4>& t = source->tangents[v];
    return identity ? Vec3d{t[0], t[1], t[2]} : placed.apply_vector(Vec3d{t[0], t[1], t[2]});
  }
  Vec3d normal(u32 v) const {
    const Vec3d turned = identity ? source->normals[v] : placed.apply_normal(source->normals[v]);
    const double length_squared_n = length_squared(turned);
    return length_squared_n > 0 ? turned / std::sqrt(length_squared_n) : Vec3d{0, 0, 0};
  }
  // The root's box, in double, before scaling.
  Aabb root() const {
    return std::visit([](const auto& b) { return scaled_box(b.nodes[0], 1); }, bvh);
  }
};

// The mesh with its vertices mapped by `placed` (the identity for a shared mesh, kept in its own space), triangles
// with zero area dropped (they can never be hit), and its BVH built.
MeshBuild build_mesh(const SceneDescription& scene, const MeshPlacementUse& use, const AffineTransform& placed) {
  const SceneMeshFile& entry = scene.mesh_files[use.file];
  const TriangleMesh& mesh = entry.file->meshes[use.mesh];
  MeshBuild out;
  out.object = use.object;
  out.name = mesh.name;
  out.source = &mesh;
  out.placed = placed;
  out.identity = placed.is_identity();
  out.has_normals = mesh.normals.size() == mesh.positions.size() && !mesh.normals.empty();
  out.has_uvs = mesh.uvs.size() == mesh.positions.size() && !mesh.uvs.empty();
  const bool file_tangents = out.has_normals && mesh.tangents.size() == mesh.positions.size();
  // The mapped vertices, for the build only (freed when it returns).
  std::vector<Vec3d> mapped;
  if (!out.identity) {
    mapped.reserve(mesh.positions.size());
    for (const Vec3d& p : mesh.positions) mapped.push_back(placed.apply_point(p));
  }
  const std::vector<Vec3d>& positions = out.identity ? mesh.positions : mapped;
  double largest_coordinate = 0;
  for (const Vec3d& p : positions) largest_coordinate = std::max({largest_coordinate, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  const bool float_boxes = float_box_fits(largest_coordinate);
  // A mirroring map turns the winding around: swap two vertices so that the front stays the front.
  const bool mirrored = placed.determinant() < 0;
  std::vector<FloatBox> float_bounds;
  std::vector<Aabb> bounds;
  out.triangles.reserve(mesh.triangles.size());
  if (float_boxes)
    float_bounds.reserve(mesh.triangles.size());
  else
    bounds.reserve(mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const std::array<u32, 3>& v = mesh.triangles[t];
    const Vec3d& a = positions[v[0]];
    const Vec3d& b = positions[v[1]];
    const Vec3d& c = positions[v[2]];
    if (length_squared(cross(b - a, c - a)) == 0) continue;
    const u32 file_material = mesh.materials.empty() ? 0 : mesh.materials[t];
    const u32 material = file_material < entry.materials.size() ? entry.materials[file_material] : entry.materials.at(0);
    out.triangles.push_back(mirrored ? MeshTriangle{{v[0], v[2], v[1]}, material} : MeshTriangle{{v[0], v[1], v[2]}, material});
    if (file_tangents && !out.has_tangents) {
      const auto* m = std::get_if<MetallicRoughness<double>>(&scene.materials[material]);
      out.has_tangents = m && m->normal_map != kNoNormalMap;
    }
    Aabb box;
    box.grow(a);
    box.grow(b);
    box.grow(c);
    if (float_boxes)
      float_bounds.push_back(outward_float_box(box));
    else
      bounds.push_back(box);
  }
  std::vector<Vec3d>().swap(mapped);
  std::vector<u32> order;
  if (float_boxes) {
    BuiltBvh<float> built = build_bvh(float_bounds);
    std::vector<FloatBox>().swap(float_bounds);
    order = std::move(built.order);
    out.bvh = std::move(built);
  } else {
    BuiltBvh<double> built = build_bvh(bounds);
    std::vector<Aabb>().swap(bounds);
    order = std::move(built.order);
    out.bvh = std::move(built);
  }
  {
    std::vector<MeshTriangle> ordered;
    ordered.reserve(out.triangles.size());
    for (u32 i : order) ordered.push_back(out.triangles[i]);
    out.triangles = std::move(ordered);
  }
  std::vector<u32>().swap(order);
  release_free_memory();  // the boxes, the order and the unordered triangles
  return out;
}

// The box of a mesh's BVH root mapped by an affine map: the box of its eight mapped corners.
Aabb mapped_box(const Aabb& root, const AffineTransform& map) {
  Aabb box;
  for (int corner = 0; corner < 8; ++corner)
    box.grow(map.apply_point(Vec3d{corner & 1 ? root.hi.x : root.lo.x, corner & 2 ? root.hi.y : root.lo.y, corner & 4 ? root.hi.z : root.lo.z}));
  return box;
}

// Appends `from` to `to` and frees it; where `to` has no storage yet (one mesh), it takes the array over instead.
template <class A>
void append_and_free(A& to, A& from) {
  if (to.capacity() == 0)
    to = std::move(from);
  else
    to.insert(to.end(), from.begin(), from.end());
  A().swap(from);
}

// The meshes' arrays in the kernels' type: vertices checked as lengths (a mesh's extent stands for its triangles'
// edges), normals and texture coordinates as plain values, the BVHs padded and their indices made global, and the
// instances' maps with their inverses and the normals' inverse transpose. Each mesh's own arrays are freed as soon
// as they are converted, so that the peak of memory stays near the result's size.
template <class T>
void flatten_meshes(const Fit<T>& fit, std::vector<MeshBuild>& meshes, const std::vector<AffineTransform>& maps, const std::vector<u32>& map_objects,
                    FlatScene<T>& flat) {
  std::size_t vertices = 0, normals = 0, uvs = 0, tangents = 0;
  for (const MeshBuild& m : meshes) {
    vertices += m.source->positions.size();
    normals += m.has_normals ? m.source->positions.size() : 0;
    uvs += m.has_uvs ? m.source->positions.size() : 0;
    tangents += m.has_tangents ? m.source->positions.size() : 0;
  }
  flat.mesh_positions.reserve(vertices);
  flat.mesh_normals.reserve(normals);
  flat.mesh_uvs.reserve(uvs);
  flat.mesh_tangents.reserve(tangents);
  if (meshes.size() > 1) {  // one mesh's arrays are taken over (append_and_free)
    std::size_t triangles = 0, nodes = 0;
    for (const MeshBuild& m : meshes) {
      triangles += m.triangles.size();
      nodes += std::visit([](const auto& b) { return b.nodes.size(); }, m.bvh);
    }
    flat.mesh_triangles.reserve(triangles);
    flat.mesh_nodes.reserve(nodes);
  }
  for (MeshBuild& m : meshes) {
    const std::string where = "/objects/" + std::to_string(m.object) + "/file";
    const std::string vertex = fmt::format("a vertex of mesh '{}'", m.name);
    const double scale = m.scale;
    const u32 vertex_count = static_cast<u32>(m.source->positions.size());
    MeshRecord record{};
    record.first_vertex = static_cast<u32>(flat.mesh_positions.size());
    for (u32 v = 0; v < vertex_count; ++v) {
      Vec3d p = m.position(v);
      if (scale != 1) p = p * scale;
      flat.mesh_positions.push_back(fit(p, Quantity::kLength, where, vertex));
    }
    const Aabb root = m.root();
    fit(root.hi * scale - root.lo * scale, Quantity::kTriangleEdge, where, fmt::format("the extent of mesh '{}', which bounds its edges", m.name));
    record.first_normal = kNoAttributes;
    if (m.has_normals) {
      record.first_normal = static_cast<u32>(flat.mesh_normals.size());
      for (u32 v = 0; v < vertex_count; ++v) flat.mesh_normals.push_back(fit(m.normal(v), Quantity::kPlain, where, "a vertex normal"));
    }
    record.first_uv = kNoAttributes;
    if (m.has_uvs) {
      record.first_uv = static_cast<u32>(flat.mesh_uvs.size());
      for (const auto& uv : m.source->uvs)
        flat.mesh_uvs.push_back(MeshUv<T>{fit(uv[0], Quantity::kPlain, where, "a texture coordinate"), fit(uv[1], Quantity::kPlain, where, "a texture coordinate")});
    }
    record.first_tangent = kNoAttributes;
    if (m.has_tangents) {
      // Unit length, so that a placement's scale cannot take them out of the type's range (only directions count).
      // The bitangent is sign * normal x tangent: a mirroring placement maps the tangent and the bitangent as
      // vectors but keeps the normal outward, so the sign turns with it.
      record.first_tangent = static_cast<u32>(flat.mesh_tangents.size());
      const double mirror = m.placed.determinant() < 0 ? -1.0 : 1.0;
      for (u32 v = 0; v < vertex_count; ++v) {
        const Vec3d t = m.tangent(v);
        const double norm = length(t);
        flat.mesh_tangents.push_back(MeshTangent<T>{fit(norm > 0 && std::isfinite(norm) ? t / norm : Vec3d{}, Quantity::kPlain, where, "a vertex tangent"),
                                                    fit(m.source->tangents[v][3] < 0 ? -mirror : mirror, Quantity::kPlain, where, "a vertex tangent")});
      }
    }
    record.first_triangle = static_cast<u32>(flat.mesh_triangles.size());
    record.triangle_count = static_cast<u32>(m.triangles.size());
    append_and_free(flat.mesh_triangles, m.triangles);
    record.root = static_cast<u32>(flat.mesh_nodes.size());
    record.wide_root = static_cast<u32>(flat.mesh_wide_nodes.size());
    std::visit(
        [&]<class S>(BuiltBvh<S>& bvh) {
          // The wide tree first, while the binary nodes are still as built; then the binary nodes, converted in
          // place where the kernels' nodes are the built ones' type.
          std::vector<WideBvhNode<T>> wide = WideBvhBuilder<T, S>(bvh.nodes, scale).build();
          for (WideBvhNode<T>& w : wide)
            for (u32 lane = 0; lane < kWideBvhWidth; ++lane) {
              if (w.leaf_mask & (1u << lane)) w.child[lane] += record.first_triangle;
              if (w.inner_mask & (1u << lane)) w.child[lane] += record.wide_root;
            }
          append_and_free(flat.mesh_wide_nodes, wide);
          auto global = [&](const BvhNode<S>& n) {
            BvhNode<T> out = padded_node<T>(n, scale);
            out.left_first += n.count > 0 ? record.first_triangle : record.root;
            return out;
          };
          if constexpr (std::is_same_v<S, T>) {
            for (BvhNode<S>& n : bvh.nodes) n = global(n);
            append_and_free(flat.mesh_nodes, bvh.nodes);
          } else {
            if (flat.mesh_nodes.capacity() == 0) flat.mesh_nodes.reserve(bvh.nodes.size());
            for (const BvhNode<S>& n : bvh.nodes) flat.mesh_nodes.push_back(global(n));
            std::vector<BvhNode<S>>().swap(bvh.nodes);
          }
        },
        m.bvh);
    flat.meshes.push_back(record);
  }
  for (std::size_t i = 0; i < maps.size(); ++i) {
    const std::string where = "/objects/" + std::to_string(map_objects[i]) + "/transform";
    const AffineTransform& to_world = maps[i];
    const AffineTransform to_mesh = to_world.inverse();
    auto rows = [&](const AffineTransform& a) {
      AffineRows<T> out;
      for (int r = 0; r < 3; ++r) out.row[r] = fit(Vec3d{a.linear[r][0], a.linear[r][1], a.linear[r][2]}, Quantity::kPlain, where, "the map placing a mesh");
      out.translation = fit(a.translation, Quantity::kLength, where, "the map placing a mesh");
      return out;
    };
    InstanceTransform<T> out;
    out.to_world = rows(to_world);
    out.to_mesh = rows(to_mesh);
    // Normals go by the inverse transpose: row r is column r of the inverse.
    for (int r = 0; r < 3; ++r)
      out.normal_rows[r] = fit(Vec3d{to_mesh.linear[0][r], to_mesh.linear[1][r], to_mesh.linear[2][r]}, Quantity::kPlain, where, "the map placing a mesh");
    flat.instance_transforms.push_back(out);
  }
}

template <class T>
FlatScene<T> flatten_scene(const SceneDescription& scene, const RenderSettings& settings, double scale) {
  std::vector<Primitive<double>> primitives, boundaries;
  std::vector<TriangleAttributes<double>> attributes;
  // Where each primitive, boundary and triangle attribute was written, for messages.
  std::vector<PrimitiveOrigin> origins, boundary_origins;
  std::vector<std::string> attribute_objects;
  std::vector<MeshPlacementUse> placements;
  for (std::size_t index = 0; index < scene.objects.size(); ++index) {
    const SceneObject object = scene.objects[index];
    const RigidTransform& xf = object.transform;
    const std::string pointer = "/objects/" + std::to_string(index);
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
        attribute_objects.push_back(pointer);
      }
      primitives.push_back({Triangle<double>{p0, p1 - p0, p2 - p0, attribute_index}, object.material});
    } else if (const auto* q = std::get_if<QuadSettings>(&object.shape)) {
      primitives.push_back({make_quad(xf.apply_point(q->corner), xf.apply_vector(q->u), xf.apply_vector(q->v)), object.material});
    } else if (const auto* b = std::get_if<BoxSettings>(&object.shape)) {
      for (const Quad<double>& face : box_faces(*b, xf)) primitives.push_back({face, object.material});
    } else if (const auto* m = std::get_if<MeshSettings>(&object.shape)) {
      const AffineTransform placed = m->transform.then(AffineTransform::from_rigid(xf));
      const MeshFile& file = *scene.mesh_files[m->file].file;
      for (const MeshPlacement& placement : file.placements) {
        if (file.meshes[placement.mesh].triangles.empty()) continue;
        // The instance's mesh field holds its placement's index until the meshes are built.
        primitives.push_back({MeshInstance<double>{static_cast<u32>(placements.size()), kNoTransform}, object.material});
        placements.push_back(MeshPlacementUse{m->file, placement.mesh, placement.transform.then(placed), static_cast<u32>(index)});
      }
    } else if (const auto* m = std::get_if<MediumSettings>(&object.shape)) {
      const RigidTransform boundary_xf = m->boundary_transform.then(xf);
      const u32 first = static_cast<u32>(boundaries.size());
      if (const auto* s = std::get_if<Sphere<double>>(&m->boundary))
        boundaries.push_back({Sphere<double>{boundary_xf.apply_point(s->center), s->radius}, object.material});
      else
        for (const Quad<double>& face : box_faces(std::get<BoxSettings>(m->boundary), boundary_xf)) boundaries.push_back({face, object.material});
      primitives.push_back({ConstantMedium<double>{first, static_cast<u32>(boundaries.size()) - first, -1.0 / m->density}, object.material});
      const bool box = std::holds_alternative<BoxSettings>(m->boundary);
      boundary_origins.resize(boundaries.size(), PrimitiveOrigin{static_cast<u32>(index), true, !boundary_xf.is_identity(), box});
    }
    origins.resize(primitives.size(), PrimitiveOrigin{static_cast<u32>(index), false, !xf.is_identity(), std::holds_alternative<BoxSettings>(object.shape)});
  }
  // Meshes: one build per mesh placed once (in world space) and one per mesh placed more often (in its own space),
  // each instance's primitive pointed at its mesh and transform, and its bounds in world space.
  std::vector<MeshBuild> meshes;
  std::vector<AffineTransform> instance_maps;  // mesh space to world, per shared instance
  std::vector<u32> instance_objects;           // the object placing each
  std::vector<Aabb> instance_bounds(placements.size());
  std::vector<u32> instance_mesh(placements.size()), instance_transform(placements.size(), kNoTransform);
  const auto meshes_start = std::chrono::steady_clock::now();
  {
    std::map<std::pair<u32, u32>, u32> uses, shared;
    for (const MeshPlacementUse& use : placements) ++uses[{use.file, use.mesh}];
    for (std::size_t i = 0; i < placements.size(); ++i) {
      const MeshPlacementUse& use = placements[i];
      const std::pair<u32, u32> key{use.file, use.mesh};
      if (uses[key] == 1) {
        instance_mesh[i] = static_cast<u32>(meshes.size());
        meshes.push_back(build_mesh(scene, use, use.transform));
        instance_bounds[i] = meshes.back().root();
        continue;
      }
      auto it = shared.find(key);
      if (it == shared.end()) {
        it = shared.emplace(key, static_cast<u32>(meshes.size())).first;
        meshes.push_back(build_mesh(scene, use, AffineTransform{}));
      }
      if (use.transform.determinant() == 0)
        throw InputError(fmt::format("{}: /objects/{}: the transform placing mesh '{}' is singular (a scale of zero)", source_position(scene, "/objects/" + std::to_string(use.object)),
                                     use.object, meshes[it->second].name));
      instance_mesh[i] = it->second;
      instance_transform[i] = static_cast<u32>(instance_maps.size());
      instance_maps.push_back(use.transform);
      instance_objects.push_back(use.object);
      instance_bounds[i] = mapped_box(meshes[it->second].root(), use.transform);
    }
  }

  const double mesh_bvh_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - meshes_start).count();
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
      } else if (const auto* instance = std::get_if<MeshInstance<double>>(&p.shape)) {
        bounds.push_back(instance_bounds[instance->mesh]);
      } else {
        bounds.push_back(geometry_bounds(p, open, close));
      }
    }
    return bounds;
  };
  std::vector<Aabb> bounds = all_bounds();

  // Fixed point: scale all lengths by a power of two (exact in binary) so that what the kernels compute stays in
  // range. Formats with exact products (ScalarTraits::kExactProducts: intersection tests, lengths and light
  // densities keep products exact and round once) square nothing in the format; they form differences of two
  // coordinates (a ray's origin to a centre, a corner, a vertex: 2 L per component for coordinates within L) and
  // distances along rays from them (|origin - centre| + radius, up to about 4.5 L), so coordinates within an eighth
  // of the largest value need no scaling: Q16.16 renders a scene within 4096 units as it is. Other formats square
  // distances: half the square root of the largest value.
  if (!(scale > 0)) {
    scale = 1;
    if constexpr (is_fixed_v<T>) {
      const double extent = scene_extent(bounds, make_camera<double>(scene.camera, settings.width, settings.height));
      const double fit = ScalarTraits<T>::kExactProducts ? static_cast<double>(largest<T>()) / 8 : std::sqrt(static_cast<double>(largest<T>())) / 2;
      if (extent > fit && std::isfinite(extent)) scale = std::exp2(std::floor(std::log2(fit / extent)));
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
    for (MeshBuild& m : meshes) m.scale = scale;  // applied as the meshes are converted
    for (AffineTransform& a : instance_maps) a.translation = a.translation * scale;
    for (Aabb& b : instance_bounds) b.lo = b.lo * scale, b.hi = b.hi * scale;
    bounds = all_bounds();
  }
  // The instances now point at their meshes and transforms.
  for (Primitive<double>& p : primitives)
    if (auto* instance = std::get_if<MeshInstance<double>>(&p.shape)) {
      const u32 use = instance->mesh;
      *instance = MeshInstance<double>{instance_mesh[use], instance_transform[use]};
    }

  // Every value of the scene the kernels get, through Fit, which refuses one out of range naming where it was written
  // (in the file's order: camera, background, textures, materials, objects). Before the BVH, which needs finite bounds.
  const Fit<T> fit(scene, scale);
  FlatScene<T> flat;
  flat.scale = scale;
  flat.camera = fit_camera(fit, camera, settings.width, settings.height);
  flat.background = Background<T>{fit(scene.background.horizon, Quantity::kColour, scene.written.horizon),
                                  fit(scene.background.zenith, Quantity::kColour, scene.written.zenith), {}};
  if (scene.environment) flatten_environment(fit, scene, flat);
  for (u32 i = 0; i < textures.size(); ++i) flat.textures.push_back(fit_texture(fit, textures[i], fit.texture(i)));
  for (u32 i = 0; i < scene.materials.size(); ++i) flat.materials.push_back(fit_material(fit, scene.materials[i], fit.material(i)));
  std::vector<Primitive<T>> converted;
  converted.reserve(primitives.size());
  for (std::size_t i = 0; i < primitives.size(); ++i) converted.push_back(fit_primitive(fit, scene, primitives[i], origins[i], open, close));
  for (std::size_t i = 0; i < boundaries.size(); ++i) flat.boundaries.push_back(fit_primitive(fit, scene, boundaries[i], boundary_origins[i], open, close));
  for (std::size_t k = 0; k < attributes.size(); ++k) {
    const TriangleAttributes<double>& a = attributes[k];
    TriangleAttributes<T> out{};
    for (int i = 0; i < 3; ++i) {
      const std::string uv = attribute_objects[k] + "/uvs/" + std::to_string(i);
      out.normal[i] = fit(a.normal[i], Quantity::kPlain, attribute_objects[k] + "/normals/" + std::to_string(i), "normalised");
      out.u[i] = fit(a.u[i], Quantity::kPlain, uv + "/0");
      out.v[i] = fit(a.v[i], Quantity::kPlain, uv + "/1");
    }
    out.has_normals = a.has_normals;
    out.has_uvs = a.has_uvs;
    flat.triangle_attributes.push_back(out);
  }

  const auto bvh_start = std::chrono::steady_clock::now();
  const BuiltBvh<double> bvh = build_bvh(bounds);
  try {
  flat.bvh_depth = bvh.depth;
  flat.nodes.reserve(bvh.nodes.size());
  for (const BvhNode<double>& n : bvh.nodes) flat.nodes.push_back(padded_node<T>(n));
  flat.wide_nodes = WideBvhBuilder<T, double>(bvh.nodes).build();
  make_perlin_tables(flat);
  flatten_meshes(fit, meshes, instance_maps, instance_objects, flat);
  flat.bvh_seconds = mesh_bvh_seconds + std::chrono::duration<double>(std::chrono::steady_clock::now() - bvh_start).count();
  } catch (const DoesNotFit& e) {
    throw InputError(fmt::format("{}: /objects: a bound of the BVH, {:g}, does not fit {} (|x| <= {:g}) after scaling lengths by {:g} (see docs/numerics.md)",
                                 scene.source, e.value, number_format_name<T>(), static_cast<double>(largest<T>()), scale));
  }
  flat.primitives.reserve(primitives.size());
  for (u32 index : bvh.order) flat.primitives.push_back(converted[index]);
  flat.texels = scene.texels;
  flat.srgb_decode = srgb_decode_table();
  flat.params = RenderParams<T>{settings.width, settings.height, settings.max_depth, settings.seed, settings.roulette_depth,
                                settings.light_sampling == LightSampling::kNextEvent ? 1u : 0u, settings.sampler};
  flat.samples_per_pixel = settings.samples_per_pixel;
  build_light_table(flat);
  return flat;
}

template <class T>
SceneView<T> FlatScene<T>::view() const {
  return place_scene(*this, [](const auto& array, const char*) { return array.data(); });
}

template <class T>
std::size_t FlatScene<T>::bytes() const {
  std::size_t total = 0;
  place_scene(*this, [&](const auto& array, const char*) {
    total += array.size() * sizeof(array[0]);
    return array.data();
  });
  return total;
}

// Written out here rather than through the traversal's intersect_leaf: this is the reference the traversal is checked
// against, so it shares only the primitive tests with it.
template <class T>
bool closest_hit_brute_force(const FlatScene<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit) {
  T closest = largest<T>();
  bool found = false;
  const SceneView<T> view = scene.view();
  for (u32 i = 0; i < scene.primitives.size(); ++i) {
    if (const auto* instance = std::get_if<MeshInstance<T>>(&scene.primitives[i].shape)) {
      // Every triangle of the mesh, in its space.
      const Ray<T> local = instance_ray(view.meshes, *instance, ray);
      const MeshRecord& mesh = scene.meshes[instance->mesh];
      MeshLeaf<T> leaf{view.meshes, mesh.first_vertex, local, hit};
      if (leaf(mesh.first_triangle, mesh.triangle_count, closest)) {
        hit.primitive = i;
        found = true;
      }
      continue;
    }
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

#define PT_INSTANTIATE_FLAT_SCENE(...)                                                                                   \
  template struct FlatScene<__VA_ARGS__>;                                                                               \
  template FlatScene<__VA_ARGS__> flatten_scene<__VA_ARGS__>(const SceneDescription&, const RenderSettings&, double); \
  template bool closest_hit_brute_force<__VA_ARGS__>(const FlatScene<__VA_ARGS__>&, const Ray<__VA_ARGS__>&,            \
                                                     const IntersectContext<__VA_ARGS__>&, Hit<__VA_ARGS__>&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_FLAT_SCENE)

}  // namespace pt
