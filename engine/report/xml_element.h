// XML as the BCF files need it: text escaped for element content and attribute values on the way out,
// and a small tree reader on the way back (bcf_reader.h). The reader takes well-formed XML 1.0 in UTF-8:
// elements, attributes, text, CDATA, character and the five predefined entity references; the prolog,
// comments, processing instructions and a DOCTYPE without an internal subset are skipped. Namespaces are
// not resolved (a prefixed name keeps its prefix). Anything else is an error naming `what` and the line.
//
// Thread safety: pure functions; an XmlElement is a plain value.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "mktree/status.h"

namespace mktree {

// `text` made safe for element content and quoted attribute values: & < > " ' escaped, characters XML 1.0
// forbids (control characters but tab, newline and carriage return) and bytes that are not UTF-8 replaced
// by U+FFFD.
std::string XmlEscape(std::string_view text);

struct XmlElement {
  std::string name;
  std::vector<std::pair<std::string, std::string>> attributes;
  std::string text;  // the character data directly inside, concatenated (entities decoded)
  std::vector<XmlElement> children;

  // The attribute's value, or "" when absent.
  std::string Attribute(std::string_view key) const;
  // The first child of that name, or nullptr.
  const XmlElement* Child(std::string_view child_name) const;
  // The text of the first child of that name, without leading and trailing white space; "" when absent.
  std::string ChildText(std::string_view child_name) const;
};

// Parses one document; its root element. `what` names the input in errors ("a.bcf: 2/markup.bcf").
Result<XmlElement> ParseXml(std::string_view xml, const std::string& what);

}  // namespace mktree
