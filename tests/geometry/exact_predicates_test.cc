#include "engine/geometry/exact_predicates.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mktree {
namespace {

using i128 = __int128;

int Sign(i128 x) { return (x > 0) - (x < 0); }

// Coordinates are integers scaled by 2^-20, so the determinants are exact in 128-bit integers.
constexpr double kScale = 0x1p-20;

int Orient2dRef(const int64_t a[2], const int64_t b[2], const int64_t c[2]) {
  const i128 l = i128(a[0] - c[0]) * (b[1] - c[1]);
  const i128 r = i128(a[1] - c[1]) * (b[0] - c[0]);
  return Sign(l - r);
}

int Orient3dRef(const int64_t a[3], const int64_t b[3], const int64_t c[3], const int64_t d[3]) {
  i128 ad[3], bd[3], cd[3];
  for (int k = 0; k < 3; ++k) ad[k] = a[k] - d[k], bd[k] = b[k] - d[k], cd[k] = c[k] - d[k];
  return Sign(ad[0] * (bd[1] * cd[2] - bd[2] * cd[1]) + ad[1] * (bd[2] * cd[0] - bd[0] * cd[2]) +
              ad[2] * (bd[0] * cd[1] - bd[1] * cd[0]));
}

// Near-degenerate points: c on the line (plane) through the others, plus an offset of -2..2 units;
// products far beyond 53 bits next to a small determinant, so plain double often loses the sign.
TEST(ExactPredicatesTest, Orient2dMatchesIntegerArithmeticNearDegeneracy) {
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<int64_t> big(-(int64_t{1} << 38), int64_t{1} << 38);
  std::uniform_int_distribution<int64_t> small(-2, 2), mult(-(1 << 25), 1 << 25), step(-(1 << 10), 1 << 10);
  int zeros = 0, nonzeros = 0, naive_wrong = 0;
  for (int it = 0; it < 20000; ++it) {
    const int64_t a[2] = {big(rng), big(rng)};
    const int64_t dir[2] = {step(rng), step(rng)};
    const int64_t t = mult(rng);  // c far from a and b: large products, small determinant
    const int64_t b[2] = {a[0] + dir[0], a[1] + dir[1]};
    const int64_t c[2] = {a[0] + t * dir[0] + small(rng), a[1] + t * dir[1] + small(rng)};
    const int want = Orient2dRef(a, b, c);
    const int got = Orient2dSign(a[0] * kScale, a[1] * kScale, b[0] * kScale, b[1] * kScale, c[0] * kScale,
                                 c[1] * kScale);
    ASSERT_EQ(got, want) << "iteration " << it;
    const double ax = a[0] * kScale, ay = a[1] * kScale, bx = b[0] * kScale, by = b[1] * kScale;
    const double cx = c[0] * kScale, cy = c[1] * kScale;
    const double naive = (ax - cx) * (by - cy) - (ay - cy) * (bx - cx);
    naive_wrong += ((naive > 0) - (naive < 0)) != want;
    // Antisymmetry under swapping two points, as the edge tests rely on.
    ASSERT_EQ(Orient2dSign(b[0] * kScale, b[1] * kScale, a[0] * kScale, a[1] * kScale, c[0] * kScale,
                           c[1] * kScale),
              -want);
    (want == 0 ? zeros : nonzeros)++;
  }
  EXPECT_GT(zeros, 500);
  EXPECT_GT(nonzeros, 1000);
  EXPECT_GT(naive_wrong, 100);  // the cases are hard: plain double gets these signs wrong
}

TEST(ExactPredicatesTest, Orient3dMatchesIntegerArithmeticNearDegeneracy) {
  std::mt19937_64 rng(2);
  std::uniform_int_distribution<int64_t> big(-(int64_t{1} << 36), int64_t{1} << 36);
  std::uniform_int_distribution<int64_t> small(-2, 2), mult(-30, 30), step(-(1 << 24), 1 << 24);
  int zeros = 0, nonzeros = 0, naive_wrong = 0;
  for (int it = 0; it < 20000; ++it) {
    const int64_t a[3] = {big(rng), big(rng), big(rng)};
    const int64_t u[3] = {step(rng), step(rng), step(rng)};
    const int64_t v[3] = {step(rng), step(rng), step(rng)};
    int64_t b[3], c[3], d[3];
    const int64_t s1 = mult(rng), t1 = mult(rng), s2 = mult(rng), t2 = mult(rng), s3 = mult(rng),
                  t3 = mult(rng);
    for (int k = 0; k < 3; ++k) {
      b[k] = a[k] + s1 * u[k] + t1 * v[k];
      c[k] = a[k] + s2 * u[k] + t2 * v[k];
      d[k] = a[k] + s3 * u[k] + t3 * v[k] + small(rng);
    }
    const int want = Orient3dRef(a, b, c, d);
    double da[3], db[3], dc[3], dd[3];
    for (int k = 0; k < 3; ++k)
      da[k] = a[k] * kScale, db[k] = b[k] * kScale, dc[k] = c[k] * kScale, dd[k] = d[k] * kScale;
    ASSERT_EQ(Orient3dSign(da, db, dc, dd), want) << "iteration " << it;
    double ad[3], bd[3], cd[3];
    for (int k = 0; k < 3; ++k) ad[k] = da[k] - dd[k], bd[k] = db[k] - dd[k], cd[k] = dc[k] - dd[k];
    const double naive = ad[0] * (bd[1] * cd[2] - bd[2] * cd[1]) + ad[1] * (bd[2] * cd[0] - bd[0] * cd[2]) +
                         ad[2] * (bd[0] * cd[1] - bd[1] * cd[0]);
    naive_wrong += ((naive > 0) - (naive < 0)) != want;
    ASSERT_EQ(Orient3dSign(db, da, dc, dd), -want);
    (want == 0 ? zeros : nonzeros)++;
  }
  EXPECT_GT(zeros, 100);
  EXPECT_GT(nonzeros, 1000);
  EXPECT_GT(naive_wrong, 100);
}

TEST(ExactPredicatesTest, FloatVerticesWithDoubleQueryPoint) {
  // Vertices are floats, the query point a double that is not a float; one ulp off the line decides.
  EXPECT_EQ(Orient2dSign(0, 0, 1, 1, 0.1, 0.1), 0);
  EXPECT_EQ(Orient2dSign(0, 0, 1, 1, 0.1, std::nextafter(0.1, 1.0)), 1);
  EXPECT_EQ(Orient2dSign(0, 0, 1, 1, 0.1, std::nextafter(0.1, 0.0)), -1);
  // Halfway along the line through two float vertices is exactly on it (halving is exact).
  const double ax = 0.1f, ay = 0.3f, bx = 0.7f, by = 0.9f;
  const double dx = bx - ax, dy = by - ay;  // exact: floats of similar magnitude
  EXPECT_EQ(Orient2dSign(ax, ay, bx, by, ax + 0.5 * dx, ay + 0.5 * dy), 0);
  const double a3[3] = {0, 0, 0}, b3[3] = {1, 0, 0}, c3[3] = {0, 1, 0};
  const double above[3] = {0.3, 0.3, 1e-30}, on[3] = {0.3, 0.3, 0};
  EXPECT_EQ(Orient3dSign(a3, b3, c3, on), 0);
  EXPECT_EQ(Orient3dSign(a3, b3, c3, above), -1);  // d above the ccw triangle abc
}

}  // namespace
}  // namespace mktree
