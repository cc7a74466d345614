// Fuzz target: a store's revision file (engine/revision/revision_manifest.h). The input is the file's text.
// The decoder must refuse it with an error naming the file, or give a manifest that encodes back to the
// same text (every byte of an accepted file is covered by its checksum, so there is one text per manifest).
#include <cstdint>
#include <cstdlib>
#include <string>

#include "engine/revision/revision_manifest.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto m = mktree::DecodeRevisionManifest(text, "rev.rev");
  if (!m.ok()) {
    if (m.status().message().find("rev.rev") == std::string::npos) std::abort();
    mktree::fuzz::Refused(m.status().ToString());
    return 0;
  }
  const std::string again = mktree::EncodeRevisionManifest(*m);
  auto m2 = mktree::DecodeRevisionManifest(again, "again");
  if (!m2.ok() || mktree::EncodeRevisionManifest(*m2) != again) std::abort();
  ++mktree::fuzz::g_accepted;
  return 0;
}
