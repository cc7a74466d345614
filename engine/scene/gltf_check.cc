// CheckGltfFile (assimp_input_checks.h): one streaming pass over the glTF JSON (a .gltf file, or the JSON
// chunk of a .glb) that measures its nesting and collects each node's "children", without recursion.
// It is not a JSON validator: assimp's parser refuses malformed JSON itself, once the nesting is known to
// be shallow enough for its recursion.
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "engine/scene/assimp_input_checks.h"

namespace mktree {

namespace {

// What a JSON container is to the check.
enum class Role { kOther, kRoot, kNodes, kNode, kChildren };

struct Container {
  Role role;
  bool is_object;
  bool expect_key;  // objects: the next string is a key
  std::string key;  // objects: the last key (kept only where it matters)
};

class GltfScan {
 public:
  explicit GltfScan(std::string path) : path_(std::move(path)) {}

  // Feeds `n` bytes of JSON.
  Status Feed(const char* p, size_t n) {
    for (size_t i = 0; i < n; ++i) MKTREE_RETURN_IF_ERROR(Byte(p[i]));
    return Status::Ok();
  }

  Status Finish() {
    // Every node has at most one parent (glTF 2.0: the nodes form disjoint trees); depth by walking up.
    const size_t n = parent_.size();
    for (size_t i = 0; i < children_.size(); ++i) {
      for (int64_t c : children_[i]) {
        if (c < 0 || static_cast<uint64_t>(c) >= n) continue;  // assimp refuses the index itself
        if (parent_[c] >= 0 && parent_[c] != static_cast<int64_t>(i))
          return Status::Corruption(path_ + ": node " + std::to_string(c) + " is a child of nodes " +
                                    std::to_string(parent_[c]) + " and " + std::to_string(i) +
                                    " (glTF nodes form trees)");
        parent_[c] = static_cast<int64_t>(i);
      }
    }
    // depth_[i]: levels from node i up to its root, 0 while unknown; computed once per node by walking up
    // to the first known ancestor, so the whole pass is linear.
    std::vector<uint32_t> depth(n, 0);
    std::vector<size_t> chain;
    for (size_t i = 0; i < n; ++i) {
      chain.clear();
      size_t at = i;
      while (depth[at] == 0) {
        chain.push_back(at);
        if (chain.size() > n) return Status::Corruption(path_ + ": the node hierarchy has a cycle");
        if (parent_[at] < 0) break;
        at = static_cast<size_t>(parent_[at]);
      }
      uint32_t d = depth[at] == 0 ? 0 : depth[at];
      for (size_t k = chain.size(); k-- > 0;) {
        d = depth[chain[k]] != 0 ? depth[chain[k]] : d + 1;
        depth[chain[k]] = d;
        if (d > kMaxNodeDepth)
          return Status::Corruption(path_ + ": nodes nested deeper than " + std::to_string(kMaxNodeDepth) +
                                    " levels");
      }
    }
    return Status::Ok();
  }

 private:
  Status Byte(char c) {
    if (in_string_) {
      if (escape_) {
        escape_ = false;
      } else if (c == '\\') {
        escape_ = true;
      } else if (c == '"') {
        in_string_ = false;
        EndString();
      } else if (keep_string_ && string_.size() < 16) {
        string_.push_back(c);
      }
      return Status::Ok();
    }
    if (in_number_ && !((c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.' || c == 'e' || c == 'E')) {
      in_number_ = false;
      EndNumber();
    }
    switch (c) {
      case '{':
      case '[': {
        if (stack_.size() >= kMaxJsonDepth)
          return Status::Corruption(path_ + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) +
                                    " levels");
        const bool object = c == '{';
        Role role = ValueRole();
        // Each role has one shape; anything else is left to assimp to refuse.
        if (object != (role == Role::kRoot || role == Role::kNode || role == Role::kOther))
          role = Role::kOther;
        if (role == Role::kNode) {
          parent_.push_back(-1);
          children_.emplace_back();
        }
        stack_.push_back({role, object, object, {}});
        break;
      }
      case '}':
      case ']':
        if (!stack_.empty()) stack_.pop_back();
        break;
      case ',':
        if (!stack_.empty() && stack_.back().is_object) stack_.back().expect_key = true;
        break;
      case ':':
        if (!stack_.empty()) stack_.back().expect_key = false;
        break;
      case '"':
        in_string_ = true;
        string_.clear();
        keep_string_ = !stack_.empty() && stack_.back().is_object && stack_.back().expect_key &&
                       (stack_.back().role == Role::kRoot || stack_.back().role == Role::kNode);
        break;
      default:
        if ((c >= '0' && c <= '9') || c == '-') {
          if (!in_number_) {
            in_number_ = true;
            number_ = 0;
            number_ok_ = c != '-';
          }
          if (c >= '0' && c <= '9' && number_ < (int64_t{1} << 40)) number_ = number_ * 10 + (c - '0');
        } else if (in_number_ || c == '.' || c == 'e' || c == 'E' || c == '+') {
          number_ok_ = false;
        }
        break;
    }
    return Status::Ok();
  }

  // The role of a value about to start in the current container.
  Role ValueRole() const {
    if (stack_.empty()) return Role::kRoot;
    const Container& top = stack_.back();
    if (top.role == Role::kRoot && top.is_object && top.key == "nodes") return Role::kNodes;
    if (top.role == Role::kNodes && !top.is_object) return Role::kNode;
    if (top.role == Role::kNode && top.is_object && top.key == "children") return Role::kChildren;
    return Role::kOther;
  }

  void EndString() {
    if (!stack_.empty() && stack_.back().is_object && stack_.back().expect_key) {
      stack_.back().key = keep_string_ ? string_ : std::string();
    }
  }

  void EndNumber() {
    if (!stack_.empty() && stack_.back().role == Role::kChildren && !children_.empty())
      children_.back().push_back(number_ok_ ? number_ : -1);
  }

  std::string path_;
  std::vector<Container> stack_;
  bool in_string_ = false, escape_ = false, keep_string_ = false;
  std::string string_;
  bool in_number_ = false, number_ok_ = false;
  int64_t number_ = 0;
  std::vector<int64_t> parent_;                 // per node: its parent, -1 for none (yet)
  std::vector<std::vector<int64_t>> children_;  // per node: its "children" (-1 for a non-index)
};

uint32_t LittleEndian32(const unsigned char* p) {
  return uint32_t{p[0]} | uint32_t{p[1]} << 8 | uint32_t{p[2]} << 16 | uint32_t{p[3]} << 24;
}

}  // namespace

Status CheckGltfFile(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) return Status::IOError(path + ": cannot open: " + std::strerror(errno));
  // A .glb: a 12-byte header ("glTF", version, length), then the JSON chunk (length, "JSON", data).
  unsigned char head[20] = {};
  const size_t got = std::fread(head, 1, sizeof head, f.get());
  uint64_t json_bytes = UINT64_MAX;
  GltfScan scan(path);
  if (got >= 4 && std::memcmp(head, "glTF", 4) == 0) {
    if (got < 20 || std::memcmp(head + 16, "JSON", 4) != 0)
      return Status::Corruption(path + ": GLB without a JSON chunk first");
    json_bytes = LittleEndian32(head + 12);
  } else {
    MKTREE_RETURN_IF_ERROR(scan.Feed(reinterpret_cast<const char*>(head), got));
  }
  std::vector<char> buf(1 << 20);
  while (json_bytes > 0) {
    const size_t want = static_cast<size_t>(std::min<uint64_t>(buf.size(), json_bytes));
    const size_t n = std::fread(buf.data(), 1, want, f.get());
    if (n == 0) break;  // a short GLB: assimp reports it
    MKTREE_RETURN_IF_ERROR(scan.Feed(buf.data(), n));
    if (json_bytes != UINT64_MAX) json_bytes -= n;
  }
  if (std::ferror(f.get())) return Status::IOError(path + ": read failed");
  return scan.Finish();
}

}  // namespace mktree
