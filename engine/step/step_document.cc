#include "engine/step/step_document.h"

#include <IFSelect_ReturnStatus.hxx>
#include <Interface_Check.hxx>
#include <Interface_CheckIterator.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_Printer.hxx>
#include <STEPCAFControl_Reader.hxx>
#include <Standard_ErrorHandler.hxx>
#include <Standard_Failure.hxx>
#include <StepData_StepModel.hxx>
#include <TDF_LabelSequence.hxx>
#include <Transfer_TransientProcess.hxx>
#include <XCAFApp_Application.hxx>
#include <XCAFDoc_DocumentTool.hxx>
#include <XCAFDoc_ShapeTool.hxx>
#include <XSControl_TransferReader.hxx>
#include <XSControl_WorkSession.hxx>
#include <algorithm>
#include <fstream>
#include <mutex>

#include "engine/step/occt_signal_guard.h"

namespace mktree {

namespace {

// OCCT's messages, kept instead of printed (its default printer writes to stdout, where mktree's output
// goes). The default messenger's only printer while a file is read.
class CollectingPrinter final : public Message_Printer {
 public:
  std::vector<std::string> lines;     // warnings and failures, the first 64
  std::vector<std::string> failures;  // failures only, the first 64
  size_t failure_count = 0;

 protected:
  void send(const TCollection_AsciiString& text, const Message_Gravity gravity) const override {
    if (gravity < Message_Warning) return;
    std::string line = text.ToCString();
    std::replace(line.begin(), line.end(), '\n', ' ');
    // OCCT frames its errors in asterisks ("**** ERR StepFile : ... ****").
    const size_t begin = line.find_first_not_of("* "), end = line.find_last_not_of("* ");
    line = begin == std::string::npos ? "" : line.substr(begin, end - begin + 1);
    if (line.empty()) return;
    auto* self = const_cast<CollectingPrinter*>(this);
    if (gravity >= Message_Fail) {
      ++self->failure_count;
      if (failures.size() < 64) self->failures.push_back(line);
    }
    if (lines.size() < 64) self->lines.push_back(std::move(line));
  }
};

// The first `bytes` of the file, or an IOError.
Result<std::string> ReadHead(const std::string& path, size_t bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IOError(path + ": cannot be opened");
  std::string head(bytes, '\0');
  in.read(head.data(), static_cast<std::streamsize>(bytes));
  head.resize(static_cast<size_t>(in.gcount()));
  return head;
}

// The first name of FILE_SCHEMA(('NAME { ... }')), or "" when the head has none.
std::string SchemaName(const std::string& head) {
  const size_t at = head.find("FILE_SCHEMA");
  if (at == std::string::npos) return "";
  const size_t open = head.find('\'', at);
  if (open == std::string::npos) return "";
  size_t end = open + 1;
  while (end < head.size() && head[end] != '\'' && head[end] != ' ' && head[end] != '{') ++end;
  return head.substr(open + 1, end - open - 1);
}

bool SupportedSchema(const std::string& schema) {
  static const char* const kPrefixes[] = {"CONFIG_CONTROL_DESIGN",
                                          "AUTOMOTIVE_DESIGN",
                                          "AP203",
                                          "AP214",
                                          "AP242",
                                          "STRUCTURAL_ANALYSIS_DESIGN",
                                          "AP209"};
  std::string upper = schema;
  std::transform(upper.begin(), upper.end(), upper.begin(), [](unsigned char c) { return std::toupper(c); });
  for (const char* p : kPrefixes)
    if (upper.rfind(p, 0) == 0) return true;
  return false;
}

Status CheckHeader(const std::string& path, std::string* schema) {
  MKTREE_ASSIGN_OR_RETURN(const std::string head, ReadHead(path, 65536));
  const size_t start = head.find_first_not_of(" \t\r\n");
  if (start == std::string::npos || head.compare(start, 13, "ISO-10303-21;") != 0)
    return Status::Corruption(path + ": not a STEP file: it does not start with ISO-10303-21;");
  *schema = SchemaName(head);
  if (schema->empty()) return Status::Corruption(path + ": no FILE_SCHEMA in the STEP header");
  if (!SupportedSchema(*schema))
    return Status::Unsupported(path + ": STEP schema " + *schema +
                               " is not read (AP203, AP214, AP242 and AP209 are)");
  return Status::Ok();
}

std::mutex& OcctTranslatorMutex() {
  static std::mutex mutex;
  return mutex;
}

void CloseUnlocked(StepDocument* document) {
  if (document->doc.IsNull()) return;
  try {
    XCAFApp_Application::GetApplication()->Close(document->doc);
  } catch (const Standard_Failure&) {
    // The document is let go below all the same.
  }
  document->doc.Nullify();
}

std::string FirstRemark(const std::vector<std::string>& remarks) {
  return remarks.empty() ? "" : ": " + remarks.front();
}

// Counts the failures of `checks` into `out`, keeping the first few named by their entity ("#57
// StepShape_ManifoldSolidBrep: ...").
void NoteFailures(const Interface_CheckIterator& checks, const Handle(Interface_InterfaceModel) & model,
                  StepDocument* out) {
  const Handle(StepData_StepModel) step = Handle(StepData_StepModel)::DownCast(model);
  for (checks.Start(); checks.More(); checks.Next()) {
    const Handle(Interface_Check)& check = checks.Value();
    if (check.IsNull() || !check->HasFailed()) continue;
    out->read_failure_count += static_cast<size_t>(check->NbFails());
    if (out->read_failures.size() >= 8) continue;
    Handle(Standard_Transient) entity = check->HasEntity() ? check->Entity() : Handle(Standard_Transient)();
    if (entity.IsNull() && !model.IsNull() && checks.Number() > 0 && checks.Number() <= model->NbEntities())
      entity = model->Value(checks.Number());
    std::string where;
    if (!entity.IsNull()) {
      const int label = step.IsNull() ? 0 : step->IdentLabel(entity);
      if (label > 0) where.append("#").append(std::to_string(label)).append(" ");
      where.append(entity->DynamicType()->Name()).append(": ");
    }
    out->read_failures.push_back(where + check->CFail(1));
  }
}

// Parses and transfers; OCCT exceptions become Corruption.
Status ReadAndTransfer(const std::string& path, StepDocument* out, std::vector<std::string>* remarks) {
  STEPCAFControl_Reader reader;
  reader.SetColorMode(true);
  reader.SetNameMode(true);
  reader.SetLayerMode(false);
  reader.SetPropsMode(false);
  reader.SetGDTMode(false);
  reader.SetMatMode(false);
  reader.SetViewMode(false);
  const IFSelect_ReturnStatus read = reader.ReadFile(path.c_str());
  if (read != IFSelect_RetDone)
    return Status::Corruption(path + ": OpenCASCADE cannot parse this STEP file" + FirstRemark(*remarks));
  const Handle(XSControl_WorkSession) session = reader.ChangeReader().WS();
  NoteFailures(session->ModelCheckList(/*complete=*/false), session->Model(), out);
  XCAFApp_Application::GetApplication()->NewDocument("MDTV-XCAF", out->doc);
  XCAFDoc_DocumentTool::SetLengthUnit(out->doc, 1.0);  // metres: the transfer converts to the document's unit
  if (!reader.Transfer(out->doc))
    return Status::Corruption(path + ": OpenCASCADE read no shape from this STEP file" +
                              FirstRemark(*remarks));
  const Handle(Transfer_TransientProcess) process = session->TransferReader()->TransientProcess();
  if (!process.IsNull()) NoteFailures(process->CheckList(/*erronly=*/true), session->Model(), out);
  return Status::Ok();
}

}  // namespace

Result<StepDocument> ReadStepDocument(const std::string& path) {
  StepDocument out;
  MKTREE_RETURN_IF_ERROR(CheckHeader(path, &out.schema));
  std::lock_guard<std::mutex> lock(OcctTranslatorMutex());
  // OCCT's default printer writes to stdout: removed for good (tessellation may speak too).
  const Handle(Message_Messenger)& messenger = Message::DefaultMessenger();
  messenger->ChangePrinters().Clear();
  Handle(CollectingPrinter) printer = new CollectingPrinter();
  messenger->AddPrinter(printer);
  Status status;
  const OcctSignalGuard signals;
  try {
    OCC_CATCH_SIGNALS
    status = ReadAndTransfer(path, &out, &printer->lines);
  } catch (const Standard_Failure& e) {
    status = Status::Corruption(path + ": OpenCASCADE failed reading it: " + e.GetMessageString());
  } catch (const std::exception& e) {
    status = Status::Corruption(path + ": OpenCASCADE failed reading it: " + e.what());
  }
  messenger->RemovePrinter(printer);
  if (status.ok()) {
    TDF_LabelSequence roots;
    XCAFDoc_DocumentTool::ShapeTool(out.doc->Main())->GetFreeShapes(roots);
    if (roots.IsEmpty()) status = Status::InvalidArgument(path + ": no shape in this STEP file");
  }
  if (!status.ok()) {
    CloseUnlocked(&out);
    return status;
  }
  out.read_failure_count += printer->failure_count;
  for (std::string& f : printer->failures)
    if (out.read_failures.size() < 8) out.read_failures.push_back(std::move(f));
  return out;
}

void CloseStepDocument(StepDocument* document) {
  std::lock_guard<std::mutex> lock(OcctTranslatorMutex());
  CloseUnlocked(document);
}

}  // namespace mktree
