// A STEP file read into an XCAF document by OpenCASCADE: the file's header and schema checked, its
// entities parsed and transferred with names and colours, lengths in metres.
// Thread-safety: ReadStepDocument may be called from any thread (calls are serialised: OCCT's translator
// keeps process-wide state); a document is used by one thread at a time.
#pragma once

#include <TDocStd_Document.hxx>
#include <string>
#include <vector>

#include "mktree/status.h"

namespace mktree {

struct StepDocument {
  Handle(TDocStd_Document) doc;
  std::string schema;  // the FILE_SCHEMA name, e.g. "AUTOMOTIVE_DESIGN"
  // Failures OCCT reported while reading a file it could still read (entities it could not translate,
  // whose shapes are missing): how many, and the first few messages.
  size_t read_failure_count = 0;
  std::vector<std::string> read_failures;
};

// Reads `path`. Corruption when it does not start with the ISO-10303-21 header or OCCT cannot parse or
// transfer it (with OCCT's first failure, naming the entity where OCCT does); Unsupported for a schema
// other than AP203, AP214, AP242 or AP209; InvalidArgument when it holds no shape. Messages name the file.
Result<StepDocument> ReadStepDocument(const std::string& path);

// Closes the document and lets it go: OCCT's application keeps every document it made until it is closed.
// Thread-safe (serialised with ReadStepDocument); nothing happens for a document without one.
void CloseStepDocument(StepDocument* document);

}  // namespace mktree
