// The small XML reader and the escaping the BCF files use: entities, CDATA, comments and both quote
// styles read; every truncation of a document and every mismatched or unknown construct is an error
// naming the input and line, never a crash; escaped text reads back as itself (bytes that are not UTF-8
// and forbidden control characters as U+FFFD).
#include "engine/report/xml_element.h"

#include <gtest/gtest.h>

#include <random>

namespace mktree {
namespace {

TEST(XmlElement, ReadsWhatBcfFilesHold) {
  const std::string doc =
      "\xef\xbb\xbf<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- a comment -->\n<!DOCTYPE Markup>\n"
      "<Markup xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\">\n"
      "  <Topic Guid='abc' TopicType=\"Clash &amp; more\">\n"
      "    <Title> A &lt;b&gt; &#233;&#x263A; </Title>\n"
      "    <Description><![CDATA[raw <b> & ]]> text</Description>\n"
      "    <Empty/>\n"
      "  </Topic>\n"
      "</Markup>\n";
  auto r = ParseXml(doc, "t.bcf");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->name, "Markup");
  const XmlElement* t = r->Child("Topic");
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->Attribute("Guid"), "abc");
  EXPECT_EQ(t->Attribute("TopicType"), "Clash & more");
  EXPECT_EQ(t->Attribute("Missing"), "");
  EXPECT_EQ(t->ChildText("Title"), "A <b> \xc3\xa9\xe2\x98\xba");
  EXPECT_EQ(t->Child("Description")->text, "raw <b> &  text");
  ASSERT_NE(t->Child("Empty"), nullptr);
  EXPECT_TRUE(t->Child("Empty")->children.empty());
  EXPECT_EQ(t->Child("Nothing"), nullptr);
}

TEST(XmlElement, ErrorsNameInputAndLine) {
  struct Case {
    const char* doc;
    const char* message;
  };
  for (const Case& c : {Case{"<a>\n<b></a>", "t.xml: line 2: </a> closes <b>"},
                        Case{"<a>\n\n&nope;</a>", "t.xml: line 3: unknown entity '&nope;'"},
                        Case{"<a x=1/>", "quoted value expected for attribute x"},
                        Case{"<a></a><b/>", "content after the root element"}, Case{"", "no root element"},
                        Case{"<a>&#0;</a>", "bad character reference"},
                        Case{"<a><!-- never closed</a>", "unterminated comment"},
                        Case{"<a x=\"<\"/>", "'<' in an attribute value"}}) {
    auto r = ParseXml(c.doc, "t.xml");
    ASSERT_FALSE(r.ok()) << c.doc;
    EXPECT_NE(r.status().message().find(c.message), std::string::npos) << r.status().message();
  }
  std::string deep;
  for (int i = 0; i < 1000; ++i) deep += "<a>";
  auto r = ParseXml(deep, "deep.xml");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("nested too deeply"), std::string::npos);
}

TEST(XmlElement, EveryTruncationIsAnError) {
  const std::string doc = "<r a=\"1\"><b>x &amp; y</b><![CDATA[z]]><c/></r>";
  ASSERT_TRUE(ParseXml(doc, "d").ok());
  for (size_t n = 0; n < doc.size(); ++n) EXPECT_FALSE(ParseXml(doc.substr(0, n), "d").ok()) << n;
}

TEST(XmlElement, EscapedTextReadsBack) {
  std::mt19937 rng(40);
  for (int round = 0; round < 2000; ++round) {
    std::string s;
    const int n = static_cast<int>(rng() % 24);
    for (int i = 0; i < n; ++i) {
      static const std::string pool[] = {"a",
                                         "<",
                                         ">",
                                         "&",
                                         "\"",
                                         "'",
                                         " ",
                                         "\t",
                                         "\n",
                                         "\r",
                                         "\xc3\xa9",
                                         "\xe2\x98\xba",
                                         "\xf0\x9f\x99\x82",
                                         "\x01",
                                         "\xff",
                                         "\xc3",
                                         "]]>"};
      s += pool[rng() % std::size(pool)];
    }
    const std::string esc = XmlEscape(s);
    auto r = ParseXml("<a v=\"" + esc + "\">" + esc + "</a>", "round");
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    // What reads back: s with each forbidden character or stray byte replaced by U+FFFD.
    std::string want;
    for (size_t i = 0; i < s.size();) {
      const auto c = static_cast<unsigned char>(s[i]);
      const size_t len = c < 0x80 ? 1 : c >= 0xf0 ? 4 : c >= 0xe0 ? 3 : 2;
      const bool whole = c < 0x80 || (c >= 0xc2 && i + len <= s.size() &&
                                      std::all_of(s.begin() + i + 1, s.begin() + i + len, [](char b) {
                                        return (static_cast<unsigned char>(b) & 0xc0) == 0x80;
                                      }));
      if (!whole || (c < 0x20 && c != '\t' && c != '\n' && c != '\r')) {
        want += "\xef\xbf\xbd";
        i += whole ? len : 1;
      } else {
        want.append(s, i, len);
        i += len;
      }
    }
    EXPECT_EQ(r->text, want);
    EXPECT_EQ(r->Attribute("v"), want);
  }
}

}  // namespace
}  // namespace mktree
