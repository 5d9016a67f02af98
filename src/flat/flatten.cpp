// Flattening: transforms applied, boxes split into quads, media given their boundary, bounds computed, BVH built,
// and every value converted from the description's double to the kernels' scalar type (flat/fit.hpp). The meshes'
// arrays are made in mesh_tables.cpp, the wide trees in wide_bvh_builder.cpp.
#include "flat/flat_scene.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <utility>
#include <variant>

#include <fmt/format.h>

#include "base/free_memory.hpp"
#include "base/number_formats.hpp"
#include "base/scalar_types.hpp"
#include "flat/bvh_builder.hpp"
#include "flat/duplicates.hpp"
#include "flat/environment.hpp"
#include "flat/fit.hpp"
#include "flat/mesh_tables.hpp"
#include "flat/wide_bvh_builder.hpp"
#include "image/image_io.hpp"
#include "scene/mesh.hpp"

namespace pt {

namespace {

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

// Texture scales whose pattern vanishes in a floating-point T: a checker or noise cell, or a texel after `repeat`,
// finer than T's spacing of the values it is looked up from (positions within `extent`, texture coordinates
// times the repeat), so that every point gets the same cell or texel (a uv_checker's at most 2^20 cells a side
// always resolve). Fixed point resolves
// texture coordinates in fixed steps whatever the value (docs/numerics.md); its range is checked by Fit.
template <class T>
void check_texture_scale(const Fit<T>& fit, const Texture<double>& texture, const std::string& at, double extent) {
  if constexpr (!is_fixed_v<T>) {
    const std::string type = number_format_name<T>();
    const auto cells = [&](double per_unit, const std::string& key, const std::string& what, double shown) {
      if (per_unit * spacing<T>(extent) >= 1)
        fit.fail(at + key, fmt::format("{:g} makes {} of {:g}, below {}'s spacing of the scene's coordinates ({:g} near {:g}): the "
                                       "pattern vanishes (at most about {:.3g})",
                                       shown, what, 1 / per_unit, type, spacing<T>(extent), extent, shown / (per_unit * spacing<T>(extent))));
    };
    if (const auto* t = std::get_if<CheckerTexture<double>>(&texture))
      cells(t->cells_per_unit, "/frequency", "checker cells", t->cells_per_unit * std::numbers::pi);
    if (const auto* t = std::get_if<NoiseTexture<double>>(&texture)) cells(t->scale, "/scale", "noise cells", t->scale);
    if (const auto* t = std::get_if<ImageTexture<double>>(&texture)) {
      const double texel = 1.0 / std::max(t->width, t->height);
      if (spacing<T>(t->repeat) >= texel)
        fit.fail(at + "/repeat", fmt::format("{:g} leaves {}'s texture coordinates too coarse to tell the image's {}x{} texels apart (at "
                                             "most about {:.3g})",
                                             t->repeat, type, t->width, t->height, t->repeat * texel / spacing<T>(t->repeat)));
    }
  }
}

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
        const Quad<T> out{fit(q.corner, Quantity::kLength, origin.pointer, "a corner of the box" + where),
                          fit(q.normal, Quantity::kPlain, origin.pointer, "a face's normal"),
                          fit(q.du * eu, dual, origin.pointer, stored + ", as a face stores it"),
                          fit(q.dv * ev, dual, origin.pointer, stored + ", as a face stores it"),
                          u_extent,
                          v_extent};
        fit(u, Quantity::kLength, origin.pointer, "an edge of the box, max - min" + where);
        fit(v, Quantity::kLength, origin.pointer, "an edge of the box, max - min" + where);
        fit(q.corner + u + v, Quantity::kLength, origin.pointer, "a corner of the box" + where);
        return out;
      }
      const std::string turned = origin.moved ? "after the object's transform" : "";
      const std::string stored_u = eu == 1 ? "1 / the length of u" : "u's dual vector times a power of two near its length";
      const std::string stored_v = ev == 1 ? "1 / the length of v" : "v's dual vector times a power of two near its length";
      const Quad<T> out{position(q.corner, "/corner"),
                        fit(q.normal, Quantity::kPlain, origin.pointer, "the normal"),
                        fit(q.du * eu, eu == 1 ? Quantity::kInverseLength : Quantity::kPlain, key("/u"), stored_u + ", as the quad stores it"),
                        fit(q.dv * ev, ev == 1 ? Quantity::kInverseLength : Quantity::kPlain, key("/v"), stored_v + ", as the quad stores it"),
                        u_extent,
                        v_extent};
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
  for (const auto& f : faces) quads.push_back(make_quad(transform.apply_point(f[0]), transform.apply_vector(f[1]), transform.apply_vector(f[2])));
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
  return Camera<T>{to<T>(c.look_from),     to<T>(lower_left),      to<T>(horizontal),         to<T>(vertical),
                   to<T>(u * lens_radius), to<T>(v * lens_radius), scalar<T>(c.shutter_open), scalar<T>(c.shutter_close - c.shutter_open)};
}

// A pixel's step across the image plane must be at least one step of T's values there, or neighbouring pixels see
// the same ray (a vertical_fov of 1e-300 gave every pixel one ray). Checked once every value has been fitted, so
// that a scene beyond the format's range is named for that first.
template <class T>
void check_pixel_resolution(const Fit<T>& fit, const CameraSettings& c, u32 width, u32 height) {
  const Camera<double> d = make_camera<double>(c, width, height);
  const auto largest_component = [](const Vec3d& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); };
  const double at =
      std::max({largest_component(d.origin), largest_component(d.lower_left), largest_component(d.lower_left + d.horizontal + d.vertical)});
  const double step = std::min(largest_component(d.horizontal) / width, largest_component(d.vertical) / height);
  if (!(step >= spacing<T>(at)))
    fit.fail("/camera/vertical_fov",
             fmt::format("{:g} degrees makes a pixel {:g} wide on the image plane{}, below {}'s spacing of coordinates there ({:g} near {:g}): "
                         "neighbouring pixels would see the same ray",
                         c.vertical_fov, step, fit.scale() != 1 ? fmt::format(" after scaling lengths by {:g}", fit.scale()) : "",
                         number_format_name<T>(), spacing<T>(at), at));
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

// The numbers that make a primitive what it is, for finding copies; nothing for media and mesh instances, which
// are kept as written.
struct ShapeNumbers {
  std::array<double, 28> values{};
  std::size_t count = 0;
  void add(const Vec3d& v) { add(v.x), add(v.y), add(v.z); }
  void add(double x) { values[count++] = x; }
  bool operator==(const ShapeNumbers& o) const { return count == o.count && std::equal(values.begin(), values.begin() + count, o.values.begin()); }
};

std::optional<ShapeNumbers> shape_numbers(const Primitive<double>& p, const std::vector<TriangleAttributes<double>>& attributes) {
  ShapeNumbers n;
  if (const auto* s = std::get_if<Sphere<double>>(&p.shape)) {
    n.add(s->center), n.add(s->radius);
  } else if (const auto* s = std::get_if<MovingSphere<double>>(&p.shape)) {
    n.add(s->center0), n.add(s->radius), n.add(s->velocity), n.add(s->time0);
  } else if (const auto* t = std::get_if<Triangle<double>>(&p.shape)) {
    n.add(t->p0), n.add(t->edge1), n.add(t->edge2);
    if (t->attributes >= 0) {
      const TriangleAttributes<double>& a = attributes[static_cast<std::size_t>(t->attributes)];
      for (int i = 0; i < 3; ++i) n.add(a.normal[i]), n.add(a.u[i]), n.add(a.v[i]);
      n.add(a.has_normals), n.add(a.has_uvs);
    }
  } else if (const auto* q = std::get_if<Quad<double>>(&p.shape)) {
    n.add(q->corner), n.add(q->du), n.add(q->dv), n.add(q->u_extent), n.add(q->v_extent);
  } else {
    return std::nullopt;
  }
  return n;
}

// Exact copies of a sphere, moving sphere, triangle or quad of the same material (for a triangle, the same normals
// and uvs too) are drawn once, as the first written: copies are hit at the same distance, where the first found
// wins, and as lights they would be sampled twice while hit once.
void drop_copies(std::deque<Primitive<double>>& primitives, const std::vector<TriangleAttributes<double>>& attributes,
                 std::deque<PrimitiveOrigin>& origins) {
  u64 uncopyable = 0;  // hashes of primitives never dropped are all different
  const std::vector<char> keep = first_of_each(
      primitives.size(),
      [&](std::size_t i) {
        const std::optional<ShapeNumbers> n = shape_numbers(primitives[i], attributes);
        if (!n) return ++uncopyable;
        BitHash hash;
        hash.add_bits(primitives[i].shape.index());
        hash.add_bits(primitives[i].material);
        for (std::size_t k = 0; k < n->count; ++k) hash.add(n->values[k]);
        return hash.value() | u64{1} << 63;  // apart from the counter's values
      },
      [&](std::size_t a, std::size_t b) {
        if (primitives[a].material != primitives[b].material || primitives[a].shape.index() != primitives[b].shape.index()) return false;
        const std::optional<ShapeNumbers> x = shape_numbers(primitives[a], attributes), y = shape_numbers(primitives[b], attributes);
        return x && y && *x == *y;
      });
  std::size_t kept = 0;
  for (std::size_t i = 0; i < primitives.size(); ++i)
    if (keep[i]) {
      primitives[kept] = primitives[i];
      origins[kept] = origins[i];
      ++kept;
    }
  primitives.resize(kept);
  origins.resize(kept);
}

// Puts primitives[i] = the primitive that was at order[i], for a permutation `order`, in place: cycle by cycle, each
// primitive moved once (a second array of a million primitives is what the large scene's peak would pay otherwise).
template <class P>
void place_in_order(std::vector<P>& primitives, const std::vector<u32>& order) {
  if (order.size() != primitives.size()) throw std::logic_error("the BVH's order is not a permutation of the primitives");
  std::vector<bool> placed(primitives.size(), false);
  for (std::size_t start = 0; start < primitives.size(); ++start) {
    if (placed[start]) continue;
    const P first = primitives[start];
    for (std::size_t i = start;;) {
      placed[i] = true;
      const std::size_t from = order[i];
      if (from == start) {
        primitives[i] = first;
        break;
      }
      primitives[i] = primitives[from];
      i = from;
    }
  }
}

// What one object of a description makes, given to a sink one part at a time, in double and world space: its
// primitives (a box's six faces; a medium after its boundary's primitives), a triangle's normals and uvs, and a
// mesh's placements. Flattening reads the objects twice through it, once for their extent and once to keep them.
template <class Sink>
void make_primitives(const SceneDescription& scene, u32 index, Sink& sink) {
  const SceneObject object = scene.objects[index];
  const RigidTransform& xf = object.transform;
  const PrimitiveOrigin origin{index, false, !xf.is_identity(), std::holds_alternative<BoxSettings>(object.shape)};
  if (const auto* s = std::get_if<Sphere<double>>(&object.shape)) {
    sink.primitive({Sphere<double>{xf.apply_point(s->center), s->radius}, object.material}, origin);
  } else if (const auto* s = std::get_if<MovingSphereSettings>(&object.shape)) {
    const Vec3d c0 = xf.apply_point(s->center0), c1 = xf.apply_point(s->center1);
    sink.primitive({MovingSphere<double>{c0, s->radius, (c1 - c0) / (s->time1 - s->time0), s->time0}, object.material}, origin);
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
      attribute_index = sink.attributes(a, index);
    }
    sink.primitive({Triangle<double>{p0, p1 - p0, p2 - p0, attribute_index}, object.material}, origin);
  } else if (const auto* q = std::get_if<QuadSettings>(&object.shape)) {
    sink.primitive({make_quad(xf.apply_point(q->corner), xf.apply_vector(q->u), xf.apply_vector(q->v)), object.material}, origin);
  } else if (const auto* b = std::get_if<BoxSettings>(&object.shape)) {
    for (const Quad<double>& face : box_faces(*b, xf)) sink.primitive({face, object.material}, origin);
  } else if (const auto* m = std::get_if<MeshSettings>(&object.shape)) {
    const AffineTransform placed = m->transform.then(AffineTransform::from_rigid(xf));
    const MeshFile& file = *scene.mesh_files[m->file].file;
    for (const MeshPlacement& placement : file.placements) {
      if (file.meshes[placement.mesh].triangles.empty()) continue;
      sink.instance(MeshPlacementUse{m->file, placement.mesh, placement.transform.then(placed), index}, object.material, origin);
    }
  } else if (const auto* m = std::get_if<MediumSettings>(&object.shape)) {
    const RigidTransform boundary_xf = m->boundary_transform.then(xf);
    const bool box = std::holds_alternative<BoxSettings>(m->boundary);
    const PrimitiveOrigin boundary_origin{index, true, !boundary_xf.is_identity(), box};
    const u32 first = sink.boundary_count();
    if (const auto* s = std::get_if<Sphere<double>>(&m->boundary))
      sink.boundary({Sphere<double>{boundary_xf.apply_point(s->center), s->radius}, object.material}, boundary_origin);
    else
      for (const Quad<double>& face : box_faces(std::get<BoxSettings>(m->boundary), boundary_xf)) sink.boundary({face, object.material}, boundary_origin);
    sink.primitive({ConstantMedium<double>{first, sink.boundary_count() - first, -1.0 / m->density}, object.material},
                   PrimitiveOrigin{index, false, !xf.is_identity(), false});
  }
}

// The first reading of the objects: the largest coordinate of any bounds (media through their boundaries, meshes
// once built) and the meshes' placements, nothing kept per object.
struct ExtentSink {
  double open = 0, close = 0;  // the shutter's interval, over which moving spheres are bounded
  double largest = 0;
  std::vector<MeshPlacementUse> placements;
  u32 boundaries = 0;

  void grow(const Aabb& b) {
    if (b.lo.x <= b.hi.x) largest = std::max({largest, max_component(vmax(b.lo, -b.lo)), max_component(vmax(b.hi, -b.hi))});
  }
  void primitive(const Primitive<double>& p, const PrimitiveOrigin&) { grow(geometry_bounds(p, open, close)); }
  void boundary(const Primitive<double>& p, const PrimitiveOrigin&) {
    grow(geometry_bounds(p, open, close));
    ++boundaries;
  }
  u32 boundary_count() const { return boundaries; }
  i32 attributes(const TriangleAttributes<double>&, u32) { return -1; }
  void instance(const MeshPlacementUse& use, u32, const PrimitiveOrigin&) { placements.push_back(use); }
};

// The second reading: every primitive kept, with where it was written. A double primitive takes 128 bytes: they are
// kept in a deque, whose blocks go as the primitives are converted.
struct GatherSink {
  std::deque<Primitive<double>> primitives;
  std::deque<PrimitiveOrigin> origins;
  std::vector<Primitive<double>> boundaries;
  std::vector<PrimitiveOrigin> boundary_origins;
  std::vector<TriangleAttributes<double>> triangle_attributes;
  std::vector<std::string> attribute_objects;
  u32 placements = 0;

  void primitive(const Primitive<double>& p, const PrimitiveOrigin& origin) {
    primitives.push_back(p);
    origins.push_back(origin);
  }
  void boundary(const Primitive<double>& p, const PrimitiveOrigin& origin) {
    boundaries.push_back(p);
    boundary_origins.push_back(origin);
  }
  u32 boundary_count() const { return static_cast<u32>(boundaries.size()); }
  i32 attributes(const TriangleAttributes<double>& a, u32 object) {
    triangle_attributes.push_back(a);
    attribute_objects.push_back("/objects/" + std::to_string(object));
    return static_cast<i32>(triangle_attributes.size() - 1);
  }
  // The instance's mesh field holds its placement's index (in the order of the first reading) until the meshes are built.
  void instance(const MeshPlacementUse&, u32 material, const PrimitiveOrigin& origin) {
    primitive({MeshInstance<double>{placements++, kNoTransform}, material}, origin);
  }
};

// The largest coordinate of the scene's bounds (`bounds_extent`), the camera and its image plane.
double scene_extent(double bounds_extent, const Camera<double>& camera) {
  double extent = bounds_extent;
  auto grow = [&](const Vec3d& p) { extent = std::max({extent, std::abs(p.x), std::abs(p.y), std::abs(p.z)}); };
  grow(camera.origin);
  grow(camera.lower_left);
  grow(camera.lower_left + camera.horizontal + camera.vertical);
  return extent;
}

// The tree over the converted primitives' bounds, in float where the scene's coordinates allow (half the memory of
// double, as for meshes), its boxes padded for T (padded_node); the binary nodes kept only where asked for.
// The bounds are let go once the binary tree is built, before the wide one is folded from it. Mesh instances (marked
// in `instances`, empty where there are none) each keep a leaf of their own: walking one is a tree walk, and two in
// one leaf would be walked in the order they are stored, not the nearer first.
template <class T, class S>
void build_scene_trees(FlatScene<T>& flat, std::vector<Box<S>>& bounds, const std::vector<bool>& instances, bool binary_tree,
                       std::vector<u32>& order) {
  BuiltBvh<S> bvh = build_bvh(bounds, instances);
  std::vector<Box<S>>().swap(bounds);
  release_free_memory();
  order = std::move(bvh.order);
  flat.bvh_depth = bvh.depth;
  std::vector<bool> instance_at;  // by position in the tree's order
  if (!instances.empty()) {
    instance_at.resize(order.size());
    for (std::size_t i = 0; i < order.size(); ++i) instance_at[i] = instances[order[i]];
  }
  flat.wide_nodes = build_wide_bvh<T, S>(bvh.nodes, 1, instance_at);
  if (binary_tree) {
    flat.nodes.reserve(bvh.nodes.size());
    for (const BvhNode<S>& n : bvh.nodes) flat.nodes.push_back(padded_node<T>(n));
  }
}

}  // namespace

// Bidirectional path tracing's unit of length in fixed point (kernel/bidirectional.hpp, "The weights' unit of length"):
// the power of two in which the camera stands at most one unit from the point it looks at, kept within 2^(F/2) of 1 (F
// fraction bits) so that the unit and lengths in it keep half the format's fraction bits. The weights are products of
// four lengths: centred on the distances the camera sees, they keep room above for the longest segments and below for
// the short ones. (The scene's extent instead, 2,000 units for seed-default's ground, left a path's segments so short
// in the unit that their fourth powers were a few steps of Q32.32: its lamp's contributions came out 7-56 % too bright.)
template <class T>
T bidirectional_unit(double camera_distance) {
  if constexpr (is_fixed_v<T>) {
    const int bound = T::kFractionBits / 2;
    const bool usable = camera_distance > 0 && std::isfinite(camera_distance);
    const int exponent = usable ? static_cast<int>(std::floor(std::log2(1 / camera_distance))) : 0;
    return T(std::exp2(std::clamp(exponent, -bound, bound)));
  } else {
    (void)camera_distance;
    return T(1);
  }
}

// Vertex merging's first radius unless asked otherwise: the width of a pixel seen at the distance from the camera to
// the point it looks at, and at most a 512th of the view's height there. A density estimate over a disc of about a
// pixel blurs the image by about a pixel, and the radius shrinks from there; a small image's pixels are too wide for
// that (the Cornell box with a glass block at 48x48: its caustic's quarter of the floor came out 22 % bright over
// 512 samples, 2.5 % with a 580th of the view's height).
static double default_merge_radius(const CameraSettings& camera, u32 height) {
  const double half_angle = camera.vertical_fov * std::numbers::pi / 360;
  return 2 * std::tan(half_angle) * length(camera.look_from - camera.look_at) / std::max(height, 512u);
}

// `released`, where the caller gives it, is `scene` itself: its parts are let go as they are converted.
template <class T>
FlatScene<T> flatten_description(const SceneDescription& scene, SceneDescription* released, const RenderSettings& settings, double scale,
                                 bool binary_tree) {
  const double open = scene.camera.shutter_open, close = scene.camera.shutter_close;
  // The objects are read twice: first for their extent, which the scale and the textures' check need before
  // anything is converted, so that the description's textures and materials can go before the primitives are made.
  ExtentSink extent_sink;
  extent_sink.open = open, extent_sink.close = close;
  for (u32 index = 0; index < scene.objects.size(); ++index) make_primitives(scene, index, extent_sink);
  const std::vector<MeshPlacementUse> placements = std::move(extent_sink.placements);
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
        throw InputError(fmt::format("{}: /objects/{}: the transform placing mesh '{}' is singular (a scale of zero)",
                                     source_position(scene, "/objects/" + std::to_string(use.object)), use.object, meshes[it->second].name));
      instance_mesh[i] = it->second;
      instance_transform[i] = static_cast<u32>(instance_maps.size());
      instance_maps.push_back(use.transform);
      instance_objects.push_back(use.object);
      instance_bounds[i] = mapped_box(meshes[it->second].root(), use.transform);
    }
  }
  const double mesh_bvh_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - meshes_start).count();
  for (const Aabb& b : instance_bounds) extent_sink.grow(b);
  const double bounds_extent = extent_sink.largest;

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
      const double extent = scene_extent(bounds_extent, make_camera<double>(scene.camera, settings.width, settings.height));
      const double fit = ScalarTraits<T>::kExactProducts ? static_cast<double>(largest<T>()) / 8 : std::sqrt(static_cast<double>(largest<T>())) / 2;
      if (extent > fit && std::isfinite(extent)) scale = std::exp2(std::floor(std::log2(fit / extent)));
    }
  }
  CameraSettings camera = scene.camera;
  std::vector<Texture<double>> textures = released ? std::move(released->textures) : scene.textures;
  if (scale != 1) {
    for (Texture<double>& t : textures) t = scaled(t, scale);
    camera.look_from = camera.look_from * scale;
    camera.look_at = camera.look_at * scale;
    camera.focus_distance *= scale;
    camera.aperture *= scale;
    for (MeshBuild& m : meshes) m.scale = scale;  // applied as the meshes are converted
    for (AffineTransform& a : instance_maps) a.translation = a.translation * scale;
    for (Aabb& b : instance_bounds) b.lo = b.lo * scale, b.hi = b.hi * scale;
  }
  // Every value of the scene the kernels get, through Fit, which refuses one out of range naming where it was written
  // (in the file's order: camera, background, textures, materials, objects). Before the BVH, which needs finite bounds.
  const Fit<T> fit(scene, scale);
  FlatScene<T> flat;
  flat.scale = scale;
  // A camera that frames a model given as the scene was not written: where it does not fit, the model's vertices
  // are at fault, and they are named (below, with the meshes) before the camera is fitted.
  if (!scene.camera_frames_model) flat.camera = fit_camera(fit, camera, settings.width, settings.height);
  flat.background = Background<T>{fit(scene.background.horizon, Quantity::kColour, scene.written.horizon),
                                  fit(scene.background.zenith, Quantity::kColour, scene.written.zenith),
                                  {}};
  if (scene.environment) flatten_environment(fit, scene, flat);
  {
    // Scaling by a power of two scales the bounds' largest coordinate exactly.
    const double extent = scene_extent(bounds_extent * scale, make_camera<double>(camera, settings.width, settings.height));
    for (u32 i = 0; i < textures.size(); ++i) check_texture_scale(fit, textures[i], fit.texture(i), extent);
  }
  // A description given to let go of loses each part once it is converted, and nothing after names it: a scene of a
  // million objects with their own materials holds about 250 bytes of them each, and the primitives in double and
  // the BVH's build that follow would otherwise find them still held.
  flat.textures.reserve(textures.size());
  flat.materials.reserve(scene.materials.size());
  for (u32 i = 0; i < textures.size(); ++i) flat.textures.push_back(fit_texture(fit, textures[i], fit.texture(i)));
  std::vector<Texture<double>>().swap(textures);
  if (released) released->written.textures = JsonPathList{};
  for (u32 i = 0; i < scene.materials.size(); ++i) flat.materials.push_back(fit_material(fit, scene.materials[i], fit.material(i)));
  if (released) {
    std::vector<Material<double>>().swap(released->materials);
    released->written.materials = JsonPathList{};
    release_free_memory();
  }

  // The second reading of the objects keeps their primitives.
  GatherSink gathered;
  for (u32 index = 0; index < scene.objects.size(); ++index) make_primitives(scene, index, gathered);
  std::deque<Primitive<double>>& primitives = gathered.primitives;
  std::deque<PrimitiveOrigin>& origins = gathered.origins;
  std::vector<Primitive<double>>& boundaries = gathered.boundaries;
  drop_copies(primitives, gathered.triangle_attributes, origins);
  // Media draw from dimension kDimMediumBase + primitive index: keep that inside 32 bits.
  if (primitives.size() >= (1ull << 31) - kDimMediumBase) throw InputError(fmt::format("{}: too many primitives", scene.source));
  if (scale != 1) {
    for (Primitive<double>& p : primitives) p = scaled(p, scale);
    for (Primitive<double>& p : boundaries) p = scaled(p, scale);
  }

  // Each primitive converted with its bounds (a medium's are its boundaries', an instance's its mesh's where placed),
  // the double primitive let go as it is: the tree's bounds in float where the scene's coordinates allow.
  const bool float_bounds = float_box_fits(bounds_extent * scale);
  std::vector<FloatBox> bounds_in_float;
  std::vector<Aabb> bounds_in_double;
  if (float_bounds)
    bounds_in_float.reserve(primitives.size());
  else
    bounds_in_double.reserve(primitives.size());
  Aabb scene_box;  // the union in double, the root of the tree: the scene's box as the lights see it
  const std::size_t primitive_count = primitives.size();
  std::vector<bool> instances;  // which primitives are mesh instances (empty where none is)
  std::vector<Primitive<T>> converted;
  converted.reserve(primitive_count);
  for (std::size_t i = 0; !primitives.empty(); ++i) {
    Primitive<double>& p = primitives.front();
    Aabb box;
    if (const auto* m = std::get_if<ConstantMedium<double>>(&p.shape)) {
      for (u32 k = 0; k < m->boundary_count; ++k) box.grow(geometry_bounds(boundaries[m->first_boundary + k], open, close));
    } else if (auto* instance = std::get_if<MeshInstance<double>>(&p.shape)) {
      const u32 use = instance->mesh;  // the placement's index until here; now its mesh and transform
      box = instance_bounds[use];
      *instance = MeshInstance<double>{instance_mesh[use], instance_transform[use]};
      if (instances.empty()) instances.resize(primitive_count);
      instances[i] = true;
    } else {
      box = geometry_bounds(p, open, close);
    }
    scene_box.grow(box);
    if (float_bounds)
      bounds_in_float.push_back(outward_float_box(box));
    else
      bounds_in_double.push_back(box);
    converted.push_back(fit_primitive(fit, scene, p, origins.front(), open, close));
    primitives.pop_front();
    origins.pop_front();
    if (i % (1u << 18) == (1u << 18) - 1) release_free_memory();  // the deque's freed blocks, back to the system
  }
  for (std::size_t i = 0; i < boundaries.size(); ++i)
    flat.boundaries.push_back(fit_primitive(fit, scene, boundaries[i], gathered.boundary_origins[i], open, close));
  if (released) released->objects = ObjectList{};  // read by the origins' messages until here
  release_free_memory();
  for (std::size_t k = 0; k < gathered.triangle_attributes.size(); ++k) {
    const TriangleAttributes<double>& a = gathered.triangle_attributes[k];
    const std::string& object = gathered.attribute_objects[k];
    TriangleAttributes<T> out{};
    for (int i = 0; i < 3; ++i) {
      const std::string uv = object + "/uvs/" + std::to_string(i);
      out.normal[i] = fit(a.normal[i], Quantity::kPlain, object + "/normals/" + std::to_string(i), "normalised");
      out.u[i] = fit(a.u[i], Quantity::kPlain, uv + "/0");
      out.v[i] = fit(a.v[i], Quantity::kPlain, uv + "/1");
    }
    out.has_normals = a.has_normals;
    out.has_uvs = a.has_uvs;
    flat.triangle_attributes.push_back(out);
  }

  const auto bvh_start = std::chrono::steady_clock::now();
  std::vector<u32> order;
  try {
    // An empty scene's box is the empty tree's root (bvh_builder.cpp).
    if (converted.empty()) scene_box = Aabb{Vec3d::splat(1), Vec3d::splat(-1)};
    const BvhNode<T> root = padded_node<T>(BvhNode<double>{scene_box.lo, 0, scene_box.hi, 0});
    flat.scene_lo = root.lo, flat.scene_hi = root.hi;
    if (float_bounds)
      build_scene_trees(flat, bounds_in_float, instances, binary_tree, order);
    else
      build_scene_trees(flat, bounds_in_double, instances, binary_tree, order);
    release_free_memory();
    make_perlin_tables(flat);
    flatten_meshes(fit, meshes, instance_maps, instance_objects, flat);
    if (scene.camera_frames_model) {
      try {
        flat.camera = fit_camera(fit, camera, settings.width, settings.height);
      } catch (const InputError&) {
        throw InputError(
            fmt::format("{}: the camera placed to frame the model, {:g} from its centre, is beyond {}'s range although the "
                        "model is not (give it a camera of its own in a scene file)",
                        scene.source, length(camera.look_from - camera.look_at), number_format_name<T>()));
      }
    }
    flat.bvh_seconds = mesh_bvh_seconds + std::chrono::duration<double>(std::chrono::steady_clock::now() - bvh_start).count();
  } catch (const DoesNotFit& e) {
    throw InputError(
        fmt::format("{}: /objects: a bound of the BVH, {:g}, does not fit {} (|x| <= {:g}) after scaling lengths by {:g} (see docs/numerics.md)",
                    scene.source, e.value, number_format_name<T>(), static_cast<double>(largest<T>()), scale));
  }
  place_in_order(converted, order);
  flat.primitives = std::move(converted);
  flat.texels = released ? std::move(released->texels) : scene.texels;
  flat.srgb_decode = srgb_decode_table();
  flat.samples_per_pixel = settings.samples_per_pixel;
  flat.noise_threshold = settings.noise_threshold;
  flat.bidirectional_schedule = settings.bidirectional_schedule;
  check_pixel_resolution(fit, camera, settings.width, settings.height);
  // auto: the background joins the lights only where scattering alone would find it noisily; with no light left,
  // paths run exactly as without light sampling.
  flat.background_scattering_variance = background_scattering_variance(flat);
  const bool sample_background =
      settings.light_sampling == LightSampling::kNextEvent || flat.background_scattering_variance > kBackgroundSamplingVariance;
  build_light_table(flat, sample_background);
  const bool next_event = settings.light_sampling != LightSampling::kNone && !flat.light_entries.empty();
  flat.params = RenderParams<T>{settings.width,    settings.height,    settings.max_depth,
                                settings.seed,     settings.roulette_depth, next_event ? 1u : 0u,
                                settings.sampler,  T(settings.light_threshold)};
  flat.params.bidirectional_unit = bidirectional_unit<T>(length(camera.look_from - camera.look_at));
  flat.merge_radius = settings.merge_radius > 0 ? settings.merge_radius * scale : default_merge_radius(camera, settings.height);
  return flat;
}

template <class T>
FlatScene<T> flatten_scene(const SceneDescription& scene, const RenderSettings& settings, double scale) {
  return flatten_description<T>(scene, nullptr, settings, scale, true);
}

template <class T>
FlatScene<T> flatten_scene_releasing(SceneDescription& scene, const RenderSettings& settings, double scale, bool binary_tree) {
  return flatten_description<T>(scene, &scene, settings, scale, binary_tree);
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
      MeshLeaf<T> leaf{view.meshes, mesh.first_vertex, local, hit, T(0)};  // nothing blocks: the closest hit
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

#define PT_INSTANTIATE_FLAT_SCENE(...)                                                                                                             \
  template struct FlatScene<__VA_ARGS__>;                                                                                                          \
  template FlatScene<__VA_ARGS__> flatten_scene<__VA_ARGS__>(const SceneDescription&, const RenderSettings&, double);                              \
  template FlatScene<__VA_ARGS__> flatten_scene_releasing<__VA_ARGS__>(SceneDescription&, const RenderSettings&, double, bool);                              \
  template bool closest_hit_brute_force<__VA_ARGS__>(const FlatScene<__VA_ARGS__>&, const Ray<__VA_ARGS__>&, const IntersectContext<__VA_ARGS__>&, \
                                                     Hit<__VA_ARGS__>&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_FLAT_SCENE)

}  // namespace pt
