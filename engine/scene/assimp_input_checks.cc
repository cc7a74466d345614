#include "engine/scene/assimp_input_checks.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>

namespace mktree {

namespace {

// The first bytes of the file, for formats recognised by content.
std::string Head(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) return {};
  char buf[64];
  return std::string(buf, std::fread(buf, 1, sizeof buf, f.get()));
}

bool StartsOffKeyword(const std::string& head) {
  size_t i = head.find_first_not_of(" \t\r\n");
  if (i == std::string::npos) return false;
  const size_t e = head.find_first_of(" \t\r\n#", i);
  const std::string k = head.substr(i, e == std::string::npos ? std::string::npos : e - i);
  return k.size() >= 3 && k.size() <= 8 && k.compare(k.size() - 3, 3, "OFF") == 0 &&
         k.find_first_not_of("STCN4nOF") == std::string::npos;
}

}  // namespace

Status CheckBeforeAssimp(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  const std::string head = Head(path);
  if (ext == ".ac" || ext == ".acc" || ext == ".ac3d" || head.rfind("AC3D", 0) == 0)
    return CheckAc3dFile(path);
  if (ext == ".off" || StartsOffKeyword(head)) return CheckOffFile(path);
  if (ext == ".ply" || head.rfind("ply\n", 0) == 0 || head.rfind("ply\r", 0) == 0) return CheckPlyFile(path);
  const size_t first = head.find_first_not_of(" \t\r\n");
  if (ext == ".gltf" || ext == ".glb" || head.rfind("glTF", 0) == 0 ||
      (first != std::string::npos && head[first] == '{'))
    return CheckGltfFile(path);
  return Status::Ok();
}

}  // namespace mktree
