#include "engine/geometry/exact_predicates.h"

#include <cmath>
#include <vector>

namespace mktree {
namespace {

// Unit roundoff of double (Shewchuk's "epsilon").
constexpr double kU = 0x1p-53;
// Filter bounds from Shewchuk, "Adaptive Precision Floating-Point Arithmetic and Fast Robust Geometric
// Predicates" (1997): valid when the first differences are computed from exact inputs, as here.
constexpr double kCcwErrBoundA = (3.0 + 16.0 * kU) * kU;
constexpr double kO3dErrBoundA = (7.0 + 56.0 * kU) * kU;

inline int SignOf(double x) { return (x > 0) - (x < 0); }

// A nonoverlapping expansion: the exact value is the sum of the components, which are kept in
// increasing magnitude with zeros removed, so the sign is the sign of the last component. Only the slow
// path uses it, so a vector is fine.
class Expansion {
 public:
  Expansion() = default;
  explicit Expansion(double x) { Grow(x); }
  static Expansion Diff(double a, double b) {  // exactly a - b
    const double x = a - b;
    const double bv = a - x;
    const double av = x + bv;
    const double err = (a - av) + (bv - b);
    Expansion e;
    e.Grow(err);
    e.Grow(x);
    return e;
  }

  // Adds b exactly (Shewchuk's GROW-EXPANSION with zero elimination).
  void Grow(double b) {
    double q = b;
    size_t out = 0;
    for (size_t i = 0; i < c_.size(); ++i) {
      const double e = c_[i];
      const double x = q + e;
      const double bv = x - q;
      const double av = x - bv;
      const double h = (q - av) + (e - bv);
      q = x;
      if (h != 0) c_[out++] = h;
    }
    c_.resize(out);
    if (q != 0 || c_.empty()) c_.push_back(q);
  }
  Expansion& operator+=(const Expansion& f) {
    for (double x : f.c_) Grow(x);
    return *this;
  }
  Expansion operator-() const {
    Expansion r = *this;
    for (double& x : r.c_) x = -x;
    return r;
  }
  Expansion operator-(const Expansion& f) const {
    Expansion r = *this;
    r += -f;
    return r;
  }
  Expansion operator*(const Expansion& f) const {
    Expansion r;
    for (double a : c_) {
      for (double b : f.c_) {
        const double p = a * b;
        const double err = std::fma(a, b, -p);  // exact product = p + err (fma is correctly rounded)
        r.Grow(err);
        r.Grow(p);
      }
    }
    return r;
  }
  int Sign() const {
    for (size_t i = c_.size(); i-- > 0;)
      if (c_[i] != 0) return SignOf(c_[i]);
    return 0;
  }

 private:
  std::vector<double> c_;
};

int Orient2dExact(double ax, double ay, double bx, double by, double cx, double cy) {
  const Expansion acx = Expansion::Diff(ax, cx), acy = Expansion::Diff(ay, cy);
  const Expansion bcx = Expansion::Diff(bx, cx), bcy = Expansion::Diff(by, cy);
  return (acx * bcy - acy * bcx).Sign();
}

int Orient3dExact(const double a[3], const double b[3], const double c[3], const double d[3]) {
  Expansion ad[3], bd[3], cd[3];
  for (int k = 0; k < 3; ++k) {
    ad[k] = Expansion::Diff(a[k], d[k]);
    bd[k] = Expansion::Diff(b[k], d[k]);
    cd[k] = Expansion::Diff(c[k], d[k]);
  }
  // (a-d) . ((b-d) x (c-d))
  Expansion det = ad[0] * (bd[1] * cd[2] - bd[2] * cd[1]);
  det += ad[1] * (bd[2] * cd[0] - bd[0] * cd[2]);
  det += ad[2] * (bd[0] * cd[1] - bd[1] * cd[0]);
  return det.Sign();
}

}  // namespace

int Orient2dSign(double ax, double ay, double bx, double by, double cx, double cy) {
  const double detleft = (ax - cx) * (by - cy);
  const double detright = (ay - cy) * (bx - cx);
  const double det = detleft - detright;
  const double detsum = std::fabs(detleft) + std::fabs(detright);
  // Both rounded products zero means a zero factor: the exact value is zero too (no underflow).
  if (detsum == 0) return 0;
  if (std::fabs(det) > kCcwErrBoundA * detsum) return SignOf(det);
  return Orient2dExact(ax, ay, bx, by, cx, cy);
}

int Orient3dSign(const double a[3], const double b[3], const double c[3], const double d[3]) {
  const double adx = a[0] - d[0], ady = a[1] - d[1], adz = a[2] - d[2];
  const double bdx = b[0] - d[0], bdy = b[1] - d[1], bdz = b[2] - d[2];
  const double cdx = c[0] - d[0], cdy = c[1] - d[1], cdz = c[2] - d[2];
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
  const double permanent = (std::fabs(bdxcdy) + std::fabs(cdxbdy)) * std::fabs(adz) +
                           (std::fabs(cdxady) + std::fabs(adxcdy)) * std::fabs(bdz) +
                           (std::fabs(adxbdy) + std::fabs(bdxady)) * std::fabs(cdz);
  if (std::fabs(det) > kO3dErrBoundA * permanent) return SignOf(det);
  return Orient3dExact(a, b, c, d);
}

}  // namespace mktree
