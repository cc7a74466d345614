// The STEP test assembly's layout (tests/data/step/engine_assembly.step): what write_step_assembly writes
// and what the STEP reader's tests expect, in the file's unit (millimetres). Header only, no OCCT.
//
//   engine                      the root assembly
//     block                     part "block": box kBlock at kBlockAt, colour kBlockColour on the solid
//     piston x kPistons         instances of the sub-assembly "piston" (unnamed: paths piston[1..3]),
//                               at kPistonAt(i), the second rotated a quarter turn about Z
//       head                    part "head": cylinder radius kHeadRadius, height kHeadHeight on the origin,
//                               colour kHeadColour on its faces only
//       rod                     part "rod": box kRod at kRodAt
//     bracket                   part "bracket": two boxes (solid[1], solid[2]), colour kBracketColour on
//                               the part, at kBracketAt
//     cover                     part "cover": five faces of a box as one open shell, at kCoverAt
//     sheet                     part "sheet": one planar face kSheet, at kSheetAt
//     extra_<k>, k < N          with --extra-parts N: distinct parts on a grid (a larger file): even k a
//                               box, odd k a cylinder of radius 4 standing in ExtraPart(k)
#pragma once

#include <array>

namespace mktree::step_test {

struct BoxMm {
  double x0, y0, z0, x1, y1, z1;
};

inline constexpr int kPistons = 3;
inline constexpr BoxMm kBlock{0, 0, 0, 200, 100, 80};
inline constexpr std::array<double, 3> kBlockAt{0, 0, 0};
inline constexpr unsigned kBlockColour = 0xcc2020;
inline constexpr double kHeadRadius = 15, kHeadHeight = 20;
inline constexpr unsigned kHeadColour = 0x2040e0;
inline constexpr BoxMm kRod{-3, -3, -40, 3, 3, 0};
inline constexpr std::array<double, 3> kRodAt{0, 0, 0};
inline constexpr BoxMm kBracketA{0, 0, 0, 10, 40, 30};
inline constexpr BoxMm kBracketB{30, 0, 0, 40, 40, 30};
inline constexpr std::array<double, 3> kBracketAt{250, 0, 0};
inline constexpr unsigned kBracketColour = 0x20a040;
inline constexpr BoxMm kCover{0, 0, 0, 50, 50, 10};  // the face at z = 10 left out
inline constexpr std::array<double, 3> kCoverAt{0, 150, 0};
inline constexpr BoxMm kSheet{0, 0, 0, 60, 30, 0};
inline constexpr std::array<double, 3> kSheetAt{100, 150, 5};

// Where piston i (0-based) stands: the sub-assembly's origin; piston 1 is also turned +90 degrees about Z.
inline constexpr std::array<double, 3> PistonAt(int i) { return {40.0 + 60.0 * i, 50.0, 120.0}; }
inline constexpr bool PistonTurned(int i) { return i == 1; }

// The box of extra part k: 8 x 8 x (4 + k % 7) mm on a 20 mm grid, 50 a row, at z = -100.
inline constexpr BoxMm ExtraPart(int k) {
  const double x = 20.0 * (k % 50), y = 20.0 * (k / 50);
  return {x, y, -100.0, x + 8, y + 8, -96.0 + k % 7};
}

}  // namespace mktree::step_test
