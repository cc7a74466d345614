#include "engine/generator/tanker_generator.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <string>

namespace mktree {
namespace {

constexpr double kHullMin[3] = {0.0, -25.0, 0.0};
constexpr double kHullMax[3] = {300.0, 25.0, 30.0};
constexpr double kPi = 3.14159265358979323846;

// ---- Portable randomness -------------------------------------------------------------------------------
// splitmix64: a fixed 64-bit mixer, so a given seed yields the same stream on every platform (unlike the
// std:: distributions, whose algorithms are left to the standard library).
uint64_t SplitMix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// Streams that keep objects independent of each other: one per (seed, what, where, which).
enum Stream : uint64_t { kCompartment = 1, kRack, kPipe, kCluster, kEquipment, kStiffener };

class Rng {
 public:
  Rng(uint64_t seed, Stream stream, uint64_t a, uint64_t b = 0)
      : state_(SplitMix(SplitMix(SplitMix(SplitMix(seed) ^ stream) ^ a) ^ b)) {}
  uint64_t Next() { return SplitMix(state_++); }
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }  // [0, 1)
  // Uniform in [lo, hi]; when hi < lo (a compartment too small for the wanted size) it returns lo.
  double Uniform(double lo, double hi) { return hi <= lo ? lo : lo + (hi - lo) * Uniform(); }
  uint32_t Below(uint32_t n) { return static_cast<uint32_t>(((Next() >> 32) * n) >> 32); }

 private:
  uint64_t state_;
};

// cos and sin from a fixed Taylor series, |theta| <= pi: libm's results may differ in the last bit
// between platforms, and the output must not.
void CosSin(double theta, double* c, double* s) {
  if (theta > kPi) theta -= 2 * kPi;
  const double x2 = theta * theta;
  double cs = 1.0, sn = 1.0;
  for (int k = 30; k >= 2; k -= 2) {
    cs = 1.0 - x2 / (k * (k - 1)) * cs;  // 1 - x^2/2! (1 - x^2/(4*3) (...))
    sn = 1.0 - x2 / ((k + 1) * k) * sn;  // 1 - x^2/3! (1 - x^2/(5*4) (...))
  }
  *c = cs;
  *s = theta * sn;
}

// Rounded to 0.1 mm: short in text, which reads back to the same doubles.
double Quantize(double v) { return std::nearbyint(v * 1e4) / 1e4; }

// ---- Closed meshes -------------------------------------------------------------------------------------
void AddVertex(Mesh* m, const double p[3]) {
  m->vertices.push_back(Quantize(p[0]));
  m->vertices.push_back(Quantize(p[1]));
  m->vertices.push_back(Quantize(p[2]));
}

void AddTriangle(Mesh* m, uint32_t a, uint32_t b, uint32_t c) {
  m->triangles.push_back(a);
  m->triangles.push_back(b);
  m->triangles.push_back(c);
}

// Axis-aligned box: vertex i has coordinate d at hi when bit d of i is set. Faces wound outward.
void AddBox(Mesh* m, const double lo[3], const double hi[3]) {
  const uint32_t base = static_cast<uint32_t>(m->vertex_count());
  for (int i = 0; i < 8; ++i) {
    const double p[3] = {(i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]};
    AddVertex(m, p);
  }
  static constexpr uint32_t kFaces[12][3] = {{0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5},
                                             {0, 1, 5}, {0, 5, 4}, {2, 6, 7}, {2, 7, 3},
                                             {0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}};
  for (const auto& f : kFaces) AddTriangle(m, base + f[0], base + f[1], base + f[2]);
}

constexpr int kMaxSides = 32;

// Right prism of `sides` sides (3 <= sides <= kMaxSides) around an axis parallel to `axis`, from s0 to s1
// along it, its centre at (cp, cq) in the two other axes p = axis+1, q = axis+2 (cyclic, so p x q = axis).
// Caps are fans.
void AddPrism(Mesh* m, int axis, double cp, double cq, double radius, double s0, double s1, int sides,
              double phase) {
  const int p = (axis + 1) % 3, q = (axis + 2) % 3;
  const uint32_t base = static_cast<uint32_t>(m->vertex_count());
  const uint32_t n = static_cast<uint32_t>(sides);
  // The unit circle, computed once for both ends and kept for the next prism: the pipes of a rack share
  // sides and phase, and the series in CosSin was most of the generator's time.
  thread_local struct {
    double phase = 0;
    int sides = 0;
    double ring[kMaxSides][2];
  } last;
  if (last.sides != sides || std::bit_cast<uint64_t>(last.phase) != std::bit_cast<uint64_t>(phase)) {
    for (int k = 0; k < sides; ++k) CosSin(phase + 2 * kPi * k / sides, &last.ring[k][0], &last.ring[k][1]);
    last.phase = phase;
    last.sides = sides;
  }
  const double(&ring)[kMaxSides][2] = last.ring;
  // Written in place (one size check per array, not one per value as AddVertex and AddTriangle do).
  const size_t v0 = m->vertices.size();
  m->vertices.resize(v0 + 6 * size_t{n});
  double* out = m->vertices.data() + v0;
  for (int end = 0; end < 2; ++end) {
    const double a = Quantize(end ? s1 : s0);
    for (int k = 0; k < sides; ++k, out += 3) {
      out[axis] = a;
      out[p] = Quantize(cp + radius * ring[k][0]);
      out[q] = Quantize(cq + radius * ring[k][1]);
    }
  }
  const size_t t0 = m->triangles.size();
  m->triangles.resize(t0 + 3 * (2 * size_t{n} + 2 * (size_t{n} - 2)));
  uint32_t* tri = m->triangles.data() + t0;
  auto add = [&tri](uint32_t a, uint32_t b, uint32_t c) {
    tri[0] = a, tri[1] = b, tri[2] = c;
    tri += 3;
  };
  // Ring points run counter-clockwise about +axis, so these windings face outward.
  for (uint32_t k = 0; k < n; ++k) {
    const uint32_t k1 = (k + 1) % n;
    add(base + k, base + k1, base + n + k1);
    add(base + k, base + n + k1, base + n + k);
  }
  for (uint32_t k = 1; k + 1 < n; ++k) {
    add(base + n, base + n + k, base + n + k + 1);  // top cap, normal +axis
    add(base, base + k + 1, base + k);              // bottom cap, normal -axis
  }
}

// ---- Layout --------------------------------------------------------------------------------------------
uint64_t PlatesAmongFirst(uint64_t m) { return (3 * m + 5) / 10; }  // round(0.3 m)
uint64_t EquipmentAmongFirst(uint64_t m) { return (m + 5) / 10; }   // round(0.1 m)

// The compartment grid for a scene of `objects` objects: nx * ny * nz cells in the hull's proportions.
struct Grid {
  uint64_t n[3] = {1, 1, 1};
  uint64_t count() const { return n[0] * n[1] * n[2]; }
};

Grid GridFor(uint64_t objects) {
  const double target = objects <= 60000 ? std::max(1.0, static_cast<double>(objects) / 60.0)
                                         : 1000.0 * std::sqrt(static_cast<double>(objects) / 60000.0);
  // Cells of side s in a 300 x 50 x 30 hull: (10t) * (5t/3) * t = target with t = 30 / s. Cube root by
  // bisection (std::cbrt is not required to be correctly rounded).
  const double v = target * 3.0 / 50.0;
  double lo = 0.0, hi = std::max(1.0, v);
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (mid * mid * mid < v ? lo : hi) = mid;
  }
  Grid g;
  g.n[0] = static_cast<uint64_t>(std::max(1LL, std::llround(10.0 * lo)));
  g.n[1] = static_cast<uint64_t>(std::max(1LL, std::llround(5.0 * lo / 3.0)));
  g.n[2] = static_cast<uint64_t>(std::max(1LL, std::llround(lo)));
  return g;
}

// Splits `count` tiles over a w x h face into gx columns and gy rows of near-square tiles.
void TileGrid(uint64_t count, double w, double h, uint64_t* gx, uint64_t* gy) {
  const long long g = std::llround(std::sqrt(static_cast<double>(count) * w / h));
  *gx = std::min<uint64_t>(count, static_cast<uint64_t>(std::max(1LL, g)));
  *gy = (count + *gx - 1) / *gx;
}

// Everything about one compartment that its objects share.
struct Compartment {
  uint64_t index = 0;
  double lo[3] = {}, hi[3] = {};        // the cell between bulkheads and decks
  double in_lo[3] = {}, in_hi[3] = {};  // its free interior, clear of deck plates and bulkhead panels
  uint64_t count = 0;                   // objects in it: plates first, then pipes, then equipment
  uint64_t plates = 0, pipes = 0, equipment = 0;
  uint64_t deck = 0, wall_x = 0, wall_y = 0, stiffeners = 0;
  uint64_t deck_g[2] = {1, 1}, wall_x_g[2] = {1, 1}, wall_y_g[2] = {1, 1};
  double deck_thickness = 0, wall_thickness = 0;
  uint32_t rack_size = 1, cluster_size = 1;
};

constexpr double kMaxDeck = 0.03;    // deck plates are at most this thick
constexpr double kPlateGap = 0.001;  // between neighbouring tiles, so plates do not share faces

class TankerSource final : public SceneSource {
 public:
  TankerSource(uint64_t objects, uint64_t seed, ObjectId first_id, uint64_t begin, uint64_t end)
      : objects_(objects),
        seed_(seed),
        first_id_(first_id),
        end_(std::min(end, objects)),
        grid_(GridFor(objects)),
        source_("tanker:" + std::to_string(objects) + ":" + std::to_string(seed)) {
    if (begin == 0 || begin >= end_) {
      Begin(0);
      emitted_ = std::min(begin, end_);
      return;
    }
    // Object `begin` directly: its compartment, its place there, and the class counts before it.
    uint64_t c = std::min(begin * grid_.count() / objects_, grid_.count() - 1);
    while (c > 0 && Start(c) > begin) --c;
    while (Start(c + 1) <= begin) ++c;
    Begin(c);
    const uint64_t first = Start(c);
    local_ = begin - first;
    emitted_ = begin;
    plate_number_ = PlatesAmongFirst(first) + std::min(local_, cell_.plates);
    equipment_number_ = EquipmentAmongFirst(first) +
                        (local_ > cell_.plates + cell_.pipes ? local_ - cell_.plates - cell_.pipes : 0);
    pipe_number_ = begin - plate_number_ - equipment_number_;
  }

  Result<bool> Next(SceneObject* out) override {
    if (static_cast<uint64_t>(first_id_) + objects_ > (uint64_t{1} << 32))
      return Status::InvalidArgument("tanker: first id " + std::to_string(first_id_) + " + " +
                                     std::to_string(objects_) + " objects exceeds the 32-bit id space");
    if (emitted_ == end_) return false;
    while (local_ == cell_.count) Begin(cell_.index + 1);
    out->mesh.vertices.clear();
    out->mesh.triangles.clear();
    out->id = static_cast<ObjectId>(first_id_ + emitted_);
    if (out->source != source_) out->source = source_;
    out->attributes.clear();
    const uint64_t i = local_;
    if (i < cell_.plates) {
      Plate(i, &out->mesh);
      Name("plate_", plate_number_++, &out->name);
    } else if (i < cell_.plates + cell_.pipes) {
      Pipe(i - cell_.plates, &out->mesh);
      Name("pipe_", pipe_number_++, &out->name);
    } else {
      Equipment(i - cell_.plates - cell_.pipes, &out->mesh);
      Name("equipment_", equipment_number_++, &out->name);
    }
    ++local_;
    ++emitted_;
    return true;
  }

 private:
  uint64_t Start(uint64_t c) const { return c * objects_ / grid_.count(); }

  void Begin(uint64_t c) {
    Compartment& k = cell_;
    k = Compartment();
    k.index = c;
    local_ = 0;
    if (c >= grid_.count()) return;
    const uint64_t iz = c % grid_.n[2], iy = (c / grid_.n[2]) % grid_.n[1],
                   ix = c / (grid_.n[2] * grid_.n[1]);
    const uint64_t idx[3] = {ix, iy, iz};
    for (int d = 0; d < 3; ++d) {
      const double span = kHullMax[d] - kHullMin[d];
      k.lo[d] = kHullMin[d] + span * static_cast<double>(idx[d]) / static_cast<double>(grid_.n[d]);
      k.hi[d] = kHullMin[d] + span * static_cast<double>(idx[d] + 1) / static_cast<double>(grid_.n[d]);
    }
    const uint64_t first = Start(c), last = Start(c + 1);
    k.count = last - first;
    k.plates = PlatesAmongFirst(last) - PlatesAmongFirst(first);
    k.equipment = EquipmentAmongFirst(last) - EquipmentAmongFirst(first);
    k.pipes = k.count - k.plates - k.equipment;

    Rng rng(seed_, kCompartment, c);
    k.deck_thickness = rng.Uniform(0.012, kMaxDeck);
    k.wall_thickness = rng.Uniform(0.010, 0.020);
    k.rack_size = 3 + rng.Below(10);
    k.cluster_size = 2 + rng.Below(4);

    // Plates: 40 % deck tiles, 30 % bulkhead panels (aft wall, then port wall), the rest stiffeners.
    k.deck = (4 * k.plates + 9) / 10;
    const uint64_t walls = std::min(k.plates - k.deck, (3 * k.plates + 9) / 10);
    k.wall_x = (walls + 1) / 2;
    k.wall_y = walls - k.wall_x;
    k.stiffeners = k.plates - k.deck - walls;
    const double w[3] = {k.hi[0] - k.lo[0], k.hi[1] - k.lo[1], k.hi[2] - k.lo[2]};
    if (k.deck) TileGrid(k.deck, w[0], w[1], &k.deck_g[0], &k.deck_g[1]);
    if (k.wall_x) TileGrid(k.wall_x, w[1], w[2], &k.wall_x_g[0], &k.wall_x_g[1]);
    if (k.wall_y) TileGrid(k.wall_y, w[0], w[2], &k.wall_y_g[0], &k.wall_y_g[1]);

    // The interior that pipes and equipment use: off the walls and the deck, within the cell.
    for (int d = 0; d < 3; ++d) {
      const double margin = std::min(0.1, 0.25 * w[d]);
      k.in_lo[d] = k.lo[d] + margin;
      k.in_hi[d] = k.hi[d] - margin;
    }
    k.in_lo[2] = std::max(k.in_lo[2], k.lo[2] + kMaxDeck + 0.01);
  }

  static void Name(const char* prefix, uint64_t number, std::string* name) {
    char digits[24];
    const auto r = std::to_chars(digits, digits + sizeof(digits), number);
    const size_t len = static_cast<size_t>(r.ptr - digits);
    name->assign(prefix);
    if (len < 6) name->append(6 - len, '0');
    name->append(digits, len);
  }

  // One tile (column, row) of a face tiled gx x gy over [a0, a1] x [b0, b1].
  static void Tile(uint64_t t, const uint64_t g[2], double a0, double a1, double b0, double b1, double* lo_a,
                   double* hi_a, double* lo_b, double* hi_b) {
    const uint64_t col = t % g[0], row = t / g[0];
    const double ta = (a1 - a0) / static_cast<double>(g[0]), tb = (b1 - b0) / static_cast<double>(g[1]);
    const double gap_a = std::min(kPlateGap, 0.05 * ta), gap_b = std::min(kPlateGap, 0.05 * tb);
    *lo_a = a0 + ta * static_cast<double>(col) + gap_a;
    *hi_a = a0 + ta * static_cast<double>(col + 1) - gap_a;
    *lo_b = b0 + tb * static_cast<double>(row) + gap_b;
    *hi_b = b0 + tb * static_cast<double>(row + 1) - gap_b;
  }

  void Plate(uint64_t i, Mesh* m) const {
    const Compartment& k = cell_;
    double lo[3], hi[3];
    const double wt = k.wall_thickness;
    const double wall_z0 = k.lo[2] + kMaxDeck + kPlateGap, wall_z1 = k.hi[2] - kPlateGap;
    if (i < k.deck) {  // deck plate on the floor of the cell
      Tile(i, k.deck_g, k.lo[0], k.hi[0], k.lo[1], k.hi[1], &lo[0], &hi[0], &lo[1], &hi[1]);
      lo[2] = k.lo[2];
      hi[2] = k.lo[2] + k.deck_thickness;
    } else if ((i -= k.deck) < k.wall_x) {  // transverse bulkhead panel on the aft wall
      Tile(i, k.wall_x_g, k.lo[1], k.hi[1], wall_z0, wall_z1, &lo[1], &hi[1], &lo[2], &hi[2]);
      lo[0] = k.lo[0];
      hi[0] = k.lo[0] + wt;
    } else if ((i -= k.wall_x) < k.wall_y) {  // longitudinal bulkhead panel on the port wall
      Tile(i, k.wall_y_g, k.lo[0] + wt + kPlateGap, k.hi[0], wall_z0, wall_z1, &lo[0], &hi[0], &lo[2],
           &hi[2]);
      lo[1] = k.lo[1];
      hi[1] = k.lo[1] + wt;
    } else {  // stiffeners: even ones are deck longitudinals under the deck above, odd ones vertical
      i -= k.wall_y;
      Rng rng(seed_, kStiffener, k.index, i);
      const uint64_t count = (i % 2 == 0) ? (k.stiffeners + 1) / 2 : k.stiffeners / 2;
      const double y0 = k.lo[1] + wt + kPlateGap, y1 = k.hi[1];
      const double y = y0 + (y1 - y0) * (static_cast<double>(i / 2) + 0.5) / static_cast<double>(count);
      const double t = 0.006;  // half the flat bar's thickness
      lo[1] = y - t;
      hi[1] = y + t;
      const double height = k.hi[2] - k.lo[2];
      if (i % 2 == 0) {
        const double h = std::min(rng.Uniform(0.15, 0.35), 0.2 * height);
        lo[0] = k.lo[0] + wt + 0.01;
        hi[0] = k.hi[0] - 0.01;
        lo[2] = k.hi[2] - kPlateGap - h;
        hi[2] = k.hi[2] - kPlateGap;
      } else {
        const double h = std::min(rng.Uniform(0.12, 0.3), 0.2 * (k.hi[0] - k.lo[0]));
        lo[0] = k.lo[0] + wt + kPlateGap;
        hi[0] = lo[0] + h;
        lo[2] = wall_z0;
        hi[2] = std::max(wall_z0 + 0.05, k.hi[2] - 0.4);
      }
    }
    AddBox(m, lo, hi);
  }

  void Pipe(uint64_t i, Mesh* m) const {
    const Compartment& k = cell_;
    const uint64_t r = i / k.rack_size, j = i % k.rack_size;
    Rng rack(seed_, kRack, k.index, r);
    const double u_axis = rack.Uniform();
    const int a = u_axis < 0.5 ? 0 : (u_axis < 0.8 ? 1 : 2);
    const int p = (a + 1) % 3, q = (a + 2) % 3;
    const double u_d = rack.Uniform();  // two draws in sequence: operand order is unspecified in C++
    const double d = 0.05 + 0.45 * u_d * rack.Uniform();  // mostly thin pipes
    const int sides = 8 + static_cast<int>(rack.Below(9));
    const double phase = rack.Uniform() * 2 * kPi / sides;
    const double pitch = 1.2 * std::min(0.5, 1.15 * d) + 0.04;
    const double ext_p = k.in_hi[p] - k.in_lo[p], ext_q = k.in_hi[q] - k.in_lo[q],
                 ext_a = k.in_hi[a] - k.in_lo[a];
    const uint64_t per_row =
        std::clamp<uint64_t>(static_cast<uint64_t>(std::max(0.0, ext_p / pitch)), 1, k.rack_size);
    const uint64_t layers = (k.rack_size + per_row - 1) / per_row;
    const double origin_p =
        k.in_lo[p] + pitch / 2 + rack.Uniform() * std::max(0.0, ext_p - static_cast<double>(per_row) * pitch);
    const double origin_q =
        k.in_lo[q] + pitch / 2 + rack.Uniform() * std::max(0.0, ext_q - static_cast<double>(layers) * pitch);
    // Length: most racks stay in the cell; long runs go through the bulkheads, up to 40 m.
    const bool long_run = rack.Uniform() < 0.35;
    const double length =
        long_run ? rack.Uniform(std::min(ext_a, 40.0), 40.0) : rack.Uniform(0.3, std::min(40.0, ext_a));
    const double start = k.in_lo[a] + rack.Uniform() * std::max(0.0, ext_a - length);
    const double end = std::max(start + std::min(0.3, ext_a), std::min(start + length, kHullMax[a] - 0.1));

    Rng pipe(seed_, kPipe, k.index, i);
    const double radius = 0.5 * std::clamp(d * pipe.Uniform(0.85, 1.15), 0.05, 0.5);
    auto place = [radius](double c, double lo, double hi) {
      return hi - lo < 2 * radius ? 0.5 * (lo + hi) : std::clamp(c, lo + radius, hi - radius);
    };
    const double cp = place(origin_p + static_cast<double>(j % per_row) * pitch, k.in_lo[p], k.in_hi[p]);
    const double cq = place(origin_q + static_cast<double>(j / per_row) * pitch, k.in_lo[q], k.in_hi[q]);
    AddPrism(m, a, cp, cq, radius, start, end, sides, phase);
  }

  void Equipment(uint64_t i, Mesh* m) const {
    const Compartment& k = cell_;
    const uint64_t c = i / k.cluster_size, j = i % k.cluster_size;
    const double ext[3] = {k.in_hi[0] - k.in_lo[0], k.in_hi[1] - k.in_lo[1], k.in_hi[2] - k.in_lo[2]};
    const double size_max = std::min({2.5, 0.45 * std::min(ext[0], ext[1]), 0.8 * ext[2]});
    const double height_max = std::min(3.0, ext[2]);

    Rng cluster(seed_, kCluster, k.index, c);
    const int row_axis = static_cast<int>(cluster.Below(2));  // pumps in a row along x or along y
    const double pitch = size_max + 0.2;
    const double centre[2] = {cluster.Uniform(k.in_lo[0], k.in_hi[0]),
                              cluster.Uniform(k.in_lo[1], k.in_hi[1])};

    Rng item(seed_, kEquipment, k.index, i);
    const double kind = item.Uniform();
    double pos[2] = {centre[0], centre[1]};
    pos[row_axis] += (static_cast<double>(j) - 0.5 * static_cast<double>(k.cluster_size - 1)) * pitch;
    auto place = [&](int axis, double half) {
      const double lo = k.in_lo[axis], hi = k.in_hi[axis];
      return hi - lo < 2 * half ? 0.5 * (lo + hi) : std::clamp(pos[axis], lo + half, hi - half);
    };
    const double floor = k.in_lo[2];
    if (kind < 0.4) {  // box: a motor, a switchboard, a skid
      const double half[2] = {0.5 * item.Uniform(0.3, size_max), 0.5 * item.Uniform(0.3, size_max)};
      const double h = item.Uniform(0.3, std::min(2.5, height_max));
      const double x = place(0, half[0]), y = place(1, half[1]);
      const double lo[3] = {x - half[0], y - half[1], floor}, hi[3] = {x + half[0], y + half[1], floor + h};
      AddBox(m, lo, hi);
    } else if (kind < 0.7) {  // vertical cylinder: a tank
      const double radius = item.Uniform(0.15, 0.5 * size_max);
      const double h = item.Uniform(0.5, height_max);
      const int sides = 16 + static_cast<int>(item.Below(9));
      AddPrism(m, 2, place(0, radius), place(1, radius), radius, floor, floor + h, sides, 0.0);
    } else {  // horizontal cylinder: a pump casing, along x or y
      const int axis = static_cast<int>(item.Below(2));
      const int other = 1 - axis;
      const double radius = std::min(item.Uniform(0.1, 0.35 * size_max), 0.5 * ext[2]);
      const double half_len = 0.5 * item.Uniform(0.4, size_max);
      const double s = place(axis, half_len), t = place(other, radius);
      const int sides = 16 + static_cast<int>(item.Below(9));
      // Prism coordinates are (p, q) = (axis + 1, axis + 2) cyclically; z is one of them.
      const double cz = floor + radius;
      if (axis == 0) {
        AddPrism(m, 0, t, cz, radius, s - half_len, s + half_len, sides, 0.0);  // p = y, q = z
      } else {
        AddPrism(m, 1, cz, t, radius, s - half_len, s + half_len, sides, 0.0);  // p = z, q = x
      }
    }
  }

  const uint64_t objects_;
  const uint64_t seed_;
  const ObjectId first_id_;
  const uint64_t end_;  // objects [emitted_ at the start, end_) are produced
  const Grid grid_;
  const std::string source_;  // "tanker:N:SEED", the spec mktree build reads it from
  Compartment cell_;
  uint64_t local_ = 0;    // next object within cell_
  uint64_t emitted_ = 0;  // objects produced so far
  uint64_t pipe_number_ = 0, plate_number_ = 0, equipment_number_ = 0;
};

}  // namespace

Box3d TankerHullBounds() {
  Box3d b;
  b.Extend(kHullMin[0], kHullMin[1], kHullMin[2]);
  b.Extend(kHullMax[0], kHullMax[1], kHullMax[2]);
  return b;
}

TankerClassCounts TankerExpectedCounts(uint64_t objects) {
  TankerClassCounts c;
  c.plates = PlatesAmongFirst(objects);
  c.equipment = EquipmentAmongFirst(objects);
  c.pipes = objects - c.plates - c.equipment;
  return c;
}

std::unique_ptr<SceneSource> MakeTankerSource(uint64_t objects, uint64_t seed, ObjectId first_id) {
  return std::make_unique<TankerSource>(objects, seed, first_id, 0, objects);
}

std::unique_ptr<SceneSource> MakeTankerRangeSource(uint64_t objects, uint64_t seed, uint64_t begin,
                                                   uint64_t end, ObjectId first_id) {
  return std::make_unique<TankerSource>(objects, seed, first_id, begin, end);
}

}  // namespace mktree
