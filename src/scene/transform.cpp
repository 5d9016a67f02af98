// Rigid transforms of scene objects (rotation about x, then y, then z, then translation).
#include <cmath>

#include "scene/scene.hpp"

namespace pt {

namespace {
void multiply(const double a[3][3], const double b[3][3], double out[3][3]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
}
}  // namespace

RigidTransform RigidTransform::from_euler_degrees(const Vec3d& degrees, const Vec3d& translation) {
  const double to_radians = 3.14159265358979323846 / 180.0;
  const double ax = degrees.x * to_radians, ay = degrees.y * to_radians, az = degrees.z * to_radians;
  const double rx[3][3] = {{1, 0, 0}, {0, std::cos(ax), -std::sin(ax)}, {0, std::sin(ax), std::cos(ax)}};
  const double ry[3][3] = {{std::cos(ay), 0, std::sin(ay)}, {0, 1, 0}, {-std::sin(ay), 0, std::cos(ay)}};
  const double rz[3][3] = {{std::cos(az), -std::sin(az), 0}, {std::sin(az), std::cos(az), 0}, {0, 0, 1}};
  double zy[3][3];
  multiply(rz, ry, zy);
  RigidTransform result;
  multiply(zy, rx, result.rotation);
  result.translation = translation;
  return result;
}

Vec3d RigidTransform::apply_vector(const Vec3d& v) const {
  return {rotation[0][0] * v.x + rotation[0][1] * v.y + rotation[0][2] * v.z,
          rotation[1][0] * v.x + rotation[1][1] * v.y + rotation[1][2] * v.z,
          rotation[2][0] * v.x + rotation[2][1] * v.y + rotation[2][2] * v.z};
}

RigidTransform RigidTransform::then(const RigidTransform& outer) const {
  RigidTransform result;
  multiply(outer.rotation, rotation, result.rotation);
  result.translation = outer.apply_point(translation);
  return result;
}

bool RigidTransform::is_identity() const {
  const RigidTransform identity;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (rotation[i][j] != identity.rotation[i][j]) return false;
  return translation.x == 0 && translation.y == 0 && translation.z == 0;
}

}  // namespace pt
