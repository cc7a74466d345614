// Test-only readers for the real meshes in MKTREE_SHARED_DATA/meshes: OFF (polygons fan-triangulated)
// and binary STL (kept as a triangle soup, one vertex per corner, as STL stores it). Small on purpose;
// the product reads these through engine/scene.
#pragma once

#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree::testing {

inline std::string SharedMeshPath(const std::string& name) {
  return std::string(MKTREE_SHARED_DATA) + "/meshes/" + name;
}

inline Result<Mesh> ReadOff(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::IOError(path + ": cannot open");
  std::string magic;
  size_t nv = 0, nf = 0, ne = 0;
  if (!(in >> magic >> nv >> nf >> ne) || magic != "OFF")
    return Status::Corruption(path + ": bad OFF header");
  Mesh m;
  m.vertices.resize(3 * nv);
  for (double& x : m.vertices)
    if (!(in >> x)) return Status::Corruption(path + ": truncated vertex list");
  for (size_t f = 0; f < nf; ++f) {
    size_t k = 0;
    if (!(in >> k) || k < 3) return Status::Corruption(path + ": bad face " + std::to_string(f));
    std::vector<uint32_t> poly(k);
    for (uint32_t& i : poly)
      if (!(in >> i) || i >= nv) return Status::Corruption(path + ": bad index in face " + std::to_string(f));
    for (size_t j = 1; j + 1 < k; ++j) m.triangles.insert(m.triangles.end(), {poly[0], poly[j], poly[j + 1]});
    std::string rest;
    std::getline(in, rest);  // optional face colour
  }
  return m;
}

inline Result<Mesh> ReadBinaryStl(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IOError(path + ": cannot open");
  char header[80];
  uint32_t n = 0;
  if (!in.read(header, 80) || !in.read(reinterpret_cast<char*>(&n), 4))
    return Status::Corruption(path + ": short header");
  Mesh m;
  m.vertices.reserve(9 * size_t{n});
  for (uint32_t t = 0; t < n; ++t) {
    char rec[50];
    if (!in.read(rec, 50)) return Status::Corruption(path + ": truncated at facet " + std::to_string(t));
    float xyz[9];
    std::memcpy(xyz, rec + 12, sizeof xyz);  // skip the normal; 2 attribute bytes follow
    m.vertices.insert(m.vertices.end(), xyz, xyz + 9);
    m.triangles.insert(m.triangles.end(), {3 * t, 3 * t + 1, 3 * t + 2});
  }
  return m;
}

inline Result<Mesh> ReadSharedMesh(const std::string& name) {
  const std::string path = SharedMeshPath(name);
  return name.ends_with(".off") ? ReadOff(path) : ReadBinaryStl(path);
}

}  // namespace mktree::testing
