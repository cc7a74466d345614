#include "engine/report/xml_element.h"

#include <cstdint>

namespace mktree {

namespace {

void AppendUtf8(uint32_t cp, std::string* out) {
  if (cp < 0x80) {
    out->push_back(static_cast<char>(cp));
  } else if (cp < 0x800) {
    out->push_back(static_cast<char>(0xc0 | cp >> 6));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3f)));
  } else if (cp < 0x10000) {
    out->push_back(static_cast<char>(0xe0 | cp >> 12));
    out->push_back(static_cast<char>(0x80 | (cp >> 6 & 0x3f)));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3f)));
  } else {
    out->push_back(static_cast<char>(0xf0 | cp >> 18));
    out->push_back(static_cast<char>(0x80 | (cp >> 12 & 0x3f)));
    out->push_back(static_cast<char>(0x80 | (cp >> 6 & 0x3f)));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3f)));
  }
}

// The length of the valid UTF-8 sequence at s[i] (1..4) and its code point, or 0 when it is not one.
size_t Utf8Sequence(std::string_view s, size_t i, uint32_t* cp) {
  const auto b = [&](size_t k) { return static_cast<uint8_t>(s[i + k]); };
  const uint8_t c = b(0);
  size_t n;
  uint32_t v, min;
  if (c < 0x80) return *cp = c, 1;
  if ((c & 0xe0) == 0xc0) {
    n = 2, v = c & 0x1f, min = 0x80;
  } else if ((c & 0xf0) == 0xe0) {
    n = 3, v = c & 0x0f, min = 0x800;
  } else if ((c & 0xf8) == 0xf0) {
    n = 4, v = c & 0x07, min = 0x10000;
  } else {
    return 0;
  }
  if (i + n > s.size()) return 0;
  for (size_t k = 1; k < n; ++k) {
    if ((b(k) & 0xc0) != 0x80) return 0;
    v = v << 6 | (b(k) & 0x3f);
  }
  if (v < min || v > 0x10ffff || (v >= 0xd800 && v <= 0xdfff) || v == 0xfffe || v == 0xffff) return 0;
  *cp = v;
  return n;
}

class Parser {
 public:
  Parser(std::string_view s, const std::string& what) : s_(s), what_(what) {}

  Result<XmlElement> Document() {
    MKTREE_RETURN_IF_ERROR(SkipMisc());
    if (!Peek('<')) return Error("no root element");
    XmlElement root;
    MKTREE_RETURN_IF_ERROR(Element(&root, 0));
    MKTREE_RETURN_IF_ERROR(SkipMisc());
    if (i_ != s_.size()) return Error("content after the root element");
    return root;
  }

 private:
  Status Error(const std::string& msg) const {
    size_t line = 1;
    for (size_t k = 0; k < i_ && k < s_.size(); ++k) line += s_[k] == '\n';
    return Status::InvalidArgument(what_ + ": line " + std::to_string(line) + ": " + msg);
  }
  bool Peek(char c) const { return i_ < s_.size() && s_[i_] == c; }
  bool Starts(std::string_view p) const { return s_.substr(i_, p.size()) == p; }
  void Space() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\n' || s_[i_] == '\r')) ++i_;
  }
  Status SkipPast(std::string_view end, const char* what) {
    const size_t k = s_.find(end, i_);
    if (k == std::string_view::npos) return Error(std::string("unterminated ") + what);
    i_ = k + end.size();
    return Status::Ok();
  }
  // White space, comments, processing instructions and a DOCTYPE outside the root.
  Status SkipMisc() {
    if (Starts("\xef\xbb\xbf")) i_ += 3;
    for (;;) {
      Space();
      if (Starts("<?")) {
        MKTREE_RETURN_IF_ERROR(SkipPast("?>", "processing instruction"));
      } else if (Starts("<!--")) {
        MKTREE_RETURN_IF_ERROR(SkipPast("-->", "comment"));
      } else if (Starts("<!DOCTYPE")) {
        MKTREE_RETURN_IF_ERROR(SkipPast(">", "DOCTYPE"));
      } else {
        return Status::Ok();
      }
    }
  }
  static bool NameChar(char c) {
    return c != ' ' && c != '\t' && c != '\n' && c != '\r' && c != '/' && c != '>' && c != '=' && c != '<' &&
           c != '"' && c != '\'';
  }
  Status Name(std::string* out) {
    const size_t b = i_;
    while (i_ < s_.size() && NameChar(s_[i_])) ++i_;
    if (i_ == b) return Error("a name was expected");
    out->assign(s_.substr(b, i_ - b));
    return Status::Ok();
  }
  // Character data up to `stop` with references decoded, appended to *out.
  Status Chars(char stop, std::string* out) {
    while (i_ < s_.size() && s_[i_] != stop) {
      if (s_[i_] == '<') return Error("'<' in an attribute value");
      if (s_[i_] != '&') {
        out->push_back(s_[i_++]);
        continue;
      }
      const size_t semi = s_.find(';', i_);
      if (semi == std::string_view::npos || semi - i_ > 12) return Error("bad entity reference");
      const std::string_view ref = s_.substr(i_ + 1, semi - i_ - 1);
      if (ref == "lt") {
        out->push_back('<');
      } else if (ref == "gt") {
        out->push_back('>');
      } else if (ref == "amp") {
        out->push_back('&');
      } else if (ref == "quot") {
        out->push_back('"');
      } else if (ref == "apos") {
        out->push_back('\'');
      } else if (ref.size() > 1 && ref[0] == '#') {
        const bool hex = ref[1] == 'x';
        uint32_t cp = 0;
        const std::string_view digits = ref.substr(hex ? 2 : 1);
        if (digits.empty()) return Error("bad character reference");
        for (char c : digits) {
          int v = c >= '0' && c <= '9' ? c - '0' : -1;
          if (hex && c >= 'a' && c <= 'f') v = c - 'a' + 10;
          if (hex && c >= 'A' && c <= 'F') v = c - 'A' + 10;
          if (v < 0 || cp > 0x10ffff) return Error("bad character reference");
          cp = cp * (hex ? 16 : 10) + static_cast<uint32_t>(v);
        }
        if (cp == 0 || cp > 0x10ffff) return Error("bad character reference");
        AppendUtf8(cp, out);
      } else {
        return Error("unknown entity '&" + std::string(ref) + ";'");
      }
      i_ = semi + 1;
    }
    return Status::Ok();
  }
  Status Attributes(XmlElement* e) {
    for (;;) {
      Space();
      if (Peek('>') || Peek('/')) return Status::Ok();
      std::pair<std::string, std::string> a;
      MKTREE_RETURN_IF_ERROR(Name(&a.first));
      Space();
      if (!Peek('=')) return Error("'=' expected after attribute " + a.first);
      ++i_;
      Space();
      if (!Peek('"') && !Peek('\'')) return Error("quoted value expected for attribute " + a.first);
      const char q = s_[i_++];
      MKTREE_RETURN_IF_ERROR(Chars(q, &a.second));
      if (!Peek(q)) return Error("unterminated value of attribute " + a.first);
      ++i_;
      e->attributes.push_back(std::move(a));
    }
  }
  Status Element(XmlElement* e, int depth) {
    if (depth > 256) return Error("elements nested too deeply");
    ++i_;  // '<'
    MKTREE_RETURN_IF_ERROR(Name(&e->name));
    MKTREE_RETURN_IF_ERROR(Attributes(e));
    if (Starts("/>")) return i_ += 2, Status::Ok();
    if (!Peek('>')) return Error("'>' expected in <" + e->name + ">");
    ++i_;
    for (;;) {
      if (i_ >= s_.size()) return Error("<" + e->name + "> is not closed");
      if (Starts("</")) {
        i_ += 2;
        std::string end;
        MKTREE_RETURN_IF_ERROR(Name(&end));
        Space();
        if (end != e->name || !Peek('>')) return Error("</" + end + "> closes <" + e->name + ">");
        ++i_;
        return Status::Ok();
      }
      if (Starts("<!--")) {
        MKTREE_RETURN_IF_ERROR(SkipPast("-->", "comment"));
      } else if (Starts("<![CDATA[")) {
        const size_t b = i_ + 9;
        MKTREE_RETURN_IF_ERROR(SkipPast("]]>", "CDATA section"));
        e->text.append(s_.substr(b, i_ - 3 - b));
      } else if (Starts("<?")) {
        MKTREE_RETURN_IF_ERROR(SkipPast("?>", "processing instruction"));
      } else if (Peek('<')) {
        e->children.emplace_back();
        MKTREE_RETURN_IF_ERROR(Element(&e->children.back(), depth + 1));
      } else {
        MKTREE_RETURN_IF_ERROR(Chars('<', &e->text));
      }
    }
  }

  std::string_view s_;
  const std::string& what_;
  size_t i_ = 0;
};

std::string Trim(std::string_view s) {
  const size_t b = s.find_first_not_of(" \t\r\n");
  if (b == std::string_view::npos) return "";
  return std::string(s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1));
}

}  // namespace

std::string XmlEscape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (size_t i = 0; i < text.size();) {
    uint32_t cp = 0;
    const size_t n = Utf8Sequence(text, i, &cp);
    if (n == 0 || (cp < 0x20 && cp != '\t' && cp != '\n' && cp != '\r')) {
      out += "\xef\xbf\xbd";
      i += n == 0 ? 1 : n;
      continue;
    }
    switch (cp) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      case '\r':
        out += "&#13;";
        break;
      default:
        out.append(text.substr(i, n));
    }
    i += n;
  }
  return out;
}

std::string XmlElement::Attribute(std::string_view key) const {
  for (const auto& [k, v] : attributes)
    if (k == key) return v;
  return "";
}

const XmlElement* XmlElement::Child(std::string_view child_name) const {
  for (const XmlElement& c : children)
    if (c.name == child_name) return &c;
  return nullptr;
}

std::string XmlElement::ChildText(std::string_view child_name) const {
  const XmlElement* c = Child(child_name);
  return c ? Trim(c->text) : "";
}

Result<XmlElement> ParseXml(std::string_view xml, const std::string& what) {
  return Parser(xml, what).Document();
}

}  // namespace mktree
