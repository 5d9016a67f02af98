// The camera: a thin lens set up on the host, and the ray of one sample of a pixel.
#pragma once

#include "kernel/random.hpp"
#include "kernel/vec3.hpp"

namespace pt {

// A thin-lens camera, set up on the host: rays start on the lens and pass through the focus plane.
template <class T>
struct Camera {
  Vec3<T> origin;
  Vec3<T> lower_left;  // corner of the image on the focus plane
  Vec3<T> horizontal, vertical;
  Vec3<T> lens_u, lens_v;  // lens radius already folded in
  T time0, time_span;
};

template <class T>
PT_HD inline Ray<T> camera_ray(const Camera<T>& camera, u32 width, u32 height, u32 x, u32 y, const SampleRandom& random) {
  T jitter_x, jitter_y, lens_u, lens_v;
  random.uniform_pair(0, kDimPixel, jitter_x, jitter_y);
  random.uniform_pair(0, kDimLens, lens_u, lens_v);
  const T s = ScalarTraits<T>::index_fraction(x, jitter_x, width);
  const T t = T(1) - ScalarTraits<T>::index_fraction(y, jitter_y, height);
  const Vec3<T> lens = uniform_in_unit_disk(lens_u, lens_v);
  const Vec3<T> origin = camera.origin + lens.x * camera.lens_u + lens.y * camera.lens_v;
  const Vec3<T> target = camera.lower_left + s * camera.horizontal + t * camera.vertical;
  const T time = camera.time0 + camera.time_span * random.uniform<T>(0, kDimTime);
  return Ray<T>{origin, normalize(target - origin), time};
}

}  // namespace pt
