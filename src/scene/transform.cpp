// Transforms of scene objects: rigid ones (rotation about x, then y, then z, then translation), and the affine maps
// that place meshes.
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
  return {rotation[0][0] * v.x + rotation[0][1] * v.y + rotation[0][2] * v.z, rotation[1][0] * v.x + rotation[1][1] * v.y + rotation[1][2] * v.z,
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

AffineTransform AffineTransform::from_rigid(const RigidTransform& rigid) {
  AffineTransform a;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a.linear[i][j] = rigid.rotation[i][j];
  a.translation = rigid.translation;
  return a;
}

AffineTransform AffineTransform::scaling(const Vec3d& factors) {
  AffineTransform a;
  a.linear[0][0] = factors.x;
  a.linear[1][1] = factors.y;
  a.linear[2][2] = factors.z;
  return a;
}

AffineTransform AffineTransform::from_column_major(const double m[16]) {
  AffineTransform a;
  for (int row = 0; row < 3; ++row)
    for (int column = 0; column < 3; ++column) a.linear[row][column] = m[column * 4 + row];
  a.translation = {m[12], m[13], m[14]};
  return a;
}

Vec3d AffineTransform::apply_vector(const Vec3d& v) const {
  return {linear[0][0] * v.x + linear[0][1] * v.y + linear[0][2] * v.z, linear[1][0] * v.x + linear[1][1] * v.y + linear[1][2] * v.z,
          linear[2][0] * v.x + linear[2][1] * v.y + linear[2][2] * v.z};
}

Vec3d AffineTransform::apply_normal(const Vec3d& n) const {
  // The inverse transpose is the cofactor matrix over the determinant; the cofactors alone keep the direction
  // (times the determinant's sign, which the caller's orientation handling must not depend on: flip it back).
  const double(&m)[3][3] = linear;
  const double c[3][3] = {{m[1][1] * m[2][2] - m[1][2] * m[2][1], m[1][2] * m[2][0] - m[1][0] * m[2][2], m[1][0] * m[2][1] - m[1][1] * m[2][0]},
                          {m[0][2] * m[2][1] - m[0][1] * m[2][2], m[0][0] * m[2][2] - m[0][2] * m[2][0], m[0][1] * m[2][0] - m[0][0] * m[2][1]},
                          {m[0][1] * m[1][2] - m[0][2] * m[1][1], m[0][2] * m[1][0] - m[0][0] * m[1][2], m[0][0] * m[1][1] - m[0][1] * m[1][0]}};
  const double sign = determinant() < 0 ? -1.0 : 1.0;
  return Vec3d{c[0][0] * n.x + c[0][1] * n.y + c[0][2] * n.z, c[1][0] * n.x + c[1][1] * n.y + c[1][2] * n.z,
               c[2][0] * n.x + c[2][1] * n.y + c[2][2] * n.z} *
         sign;
}

AffineTransform AffineTransform::then(const AffineTransform& outer) const {
  AffineTransform out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      out.linear[i][j] = outer.linear[i][0] * linear[0][j] + outer.linear[i][1] * linear[1][j] + outer.linear[i][2] * linear[2][j];
  out.translation = outer.apply_point(translation);
  return out;
}

double AffineTransform::determinant() const {
  const double(&m)[3][3] = linear;
  return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
         m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

AffineTransform AffineTransform::inverse() const {
  const double(&m)[3][3] = linear;
  const double d = determinant();
  AffineTransform out;
  out.linear[0][0] = (m[1][1] * m[2][2] - m[1][2] * m[2][1]) / d;
  out.linear[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / d;
  out.linear[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / d;
  out.linear[1][0] = (m[1][2] * m[2][0] - m[1][0] * m[2][2]) / d;
  out.linear[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / d;
  out.linear[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / d;
  out.linear[2][0] = (m[1][0] * m[2][1] - m[1][1] * m[2][0]) / d;
  out.linear[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / d;
  out.linear[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / d;
  out.translation = -out.apply_vector(translation);
  return out;
}

bool AffineTransform::is_identity() const {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (linear[i][j] != (i == j ? 1.0 : 0.0)) return false;
  return translation.x == 0 && translation.y == 0 && translation.z == 0;
}

}  // namespace pt
