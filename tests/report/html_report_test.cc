// The HTML report: worst groups first, every text escaped, members and groups bounded with the page saying
// how many are left out, snapshots inline as data: URIs that decode to the source's bytes, nothing fetched
// from a network; an unwritable path leaves nothing. In headless Chromium (when installed) the page loads,
// its script runs to the end, the filters given in the URL hide the other groups, and a screenshot shows
// the groups (not a blank page).
#include "engine/report/html_report.h"

#include <gtest/gtest.h>
#include <png.h>

#include <regex>

#include "engine/report/group_snapshot.h"
#include "report/report_fixtures.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::ProgramDir;

// A w x h PNG of one colour.
std::vector<uint8_t> SolidPng(uint32_t w, uint32_t h, uint8_t r, uint8_t g, uint8_t b) {
  std::vector<uint8_t> rgb(size_t{3} * w * h);
  for (size_t i = 0; i < rgb.size(); i += 3) rgb[i] = r, rgb[i + 1] = g, rgb[i + 2] = b;
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  img.width = w;
  img.height = h;
  img.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  EXPECT_TRUE(png_image_write_to_memory(&img, nullptr, &size, 0, rgb.data(), 0, nullptr));
  std::vector<uint8_t> out(size);
  EXPECT_TRUE(png_image_write_to_memory(&img, out.data(), &size, 0, rgb.data(), 0, nullptr));
  out.resize(size);
  return out;
}

std::vector<uint8_t> DecodeBase64(const std::string& s) {
  std::vector<uint8_t> out;
  uint32_t acc = 0;
  int bits = 0;
  for (char c : s) {
    int v = c >= 'A' && c <= 'Z'   ? c - 'A'
            : c >= 'a' && c <= 'z' ? c - 'a' + 26
            : c >= '0' && c <= '9' ? c - '0' + 52
            : c == '+'             ? 62
            : c == '/'             ? 63
                                   : -1;
    if (v < 0) break;
    acc = acc << 6 | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) out.push_back(static_cast<uint8_t>(acc >> (bits -= 8)));
  }
  return out;
}

size_t Count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

TEST(HtmlReport, WorstFirstEscapedBounded) {
  const ClashRun run = HandRun();
  HtmlReportOptions o;
  o.members_per_group = 1;
  const std::string path = ProgramDir().file("bounded.html");
  auto w = WriteHtmlReport(run, path, o);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  const std::string page = ReadFileBytes(path);
  EXPECT_EQ(w->bytes, page.size());
  EXPECT_EQ(w->groups_listed, 3u);
  EXPECT_EQ(w->members_listed, 3u);
  EXPECT_EQ(w->members_left_out, 1u);
  EXPECT_EQ(Count(page, "<section class=\"group"), 3u);
  // Worst first: the hard group, then the touch, then the clearance (the run's order differs).
  const size_t hard = page.find("<section class=\"group hard\""),
               touch = page.find("<section class=\"group touch\""),
               clear = page.find("<section class=\"group clearance\"");
  ASSERT_NE(hard, std::string::npos);
  EXPECT_LT(hard, touch);
  EXPECT_LT(touch, clear);
  EXPECT_NE(page.find("worst gap 0.03"), std::string::npos);
  EXPECT_NE(page.find("worst depth 0.04"), std::string::npos);
  EXPECT_NE(page.find("and 1 more clashes not listed (the page lists 1 per group)"), std::string::npos);
  // Escaped: the beam's name never appears raw.
  EXPECT_EQ(page.find("<B-12>"), std::string::npos);
  EXPECT_NE(page.find("Beam &lt;B-12&gt; &amp; &quot;main&quot; &#39;east&#39;"), std::string::npos);
  // The tests with their rule exclusions and warnings.
  EXPECT_NE(page.find("hosted_filling: 7"), std::string::npos);
  EXPECT_NE(page.find("selection b matched nothing"), std::string::npos);
  // Nothing from a network.
  EXPECT_EQ(page.find("http://"), std::string::npos);
  EXPECT_EQ(page.find("https://"), std::string::npos);
  EXPECT_NE(page.find("default-src 'none'"), std::string::npos);

  o.max_groups = 2;
  ASSERT_TRUE(WriteHtmlReport(run, path, o).ok());
  const std::string two = ReadFileBytes(path);
  EXPECT_EQ(Count(two, "<section class=\"group"), 2u);
  EXPECT_NE(two.find("The first 2 of 3 groups are listed"), std::string::npos);
  EXPECT_EQ(two.find("<section class=\"group clearance\""), std::string::npos);
}

TEST(HtmlReport, SnapshotsAreInlineDataUris) {
  const ClashRun run = HandRun();
  const std::vector<uint8_t> png = SolidPng(40, 30, 225, 25, 25);
  HtmlReportOptions o;
  o.snapshot = [&](const ClashGroup&) -> Result<std::vector<uint8_t>> { return png; };
  o.max_snapshots = 2;
  const std::string path = ProgramDir().file("snapshots.html");
  auto w = WriteHtmlReport(run, path, o);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  EXPECT_EQ(w->snapshots, 2u);
  const std::string page = ReadFileBytes(path);
  const std::regex uri("src=\"data:image/png;base64,([A-Za-z0-9+/=]+)\"");
  size_t n = 0;
  for (auto it = std::sregex_iterator(page.begin(), page.end(), uri); it != std::sregex_iterator(); ++it, ++n)
    EXPECT_EQ(DecodeBase64((*it)[1].str()), png);
  EXPECT_EQ(n, 2u);
}

TEST(HtmlReport, ErrorsLeaveNothing) {
  const ClashRun run = HandRun();
  const std::string bad = ProgramDir().file("missing_dir") + "/r.html";
  auto w = WriteHtmlReport(run, bad, {});
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find(bad), std::string::npos) << w.status().message();
  EXPECT_FALSE(fs::exists(ProgramDir().file("missing_dir")));
  const fs::path dir = ProgramDir() / "snapfail";
  fs::create_directories(dir);
  HtmlReportOptions o;
  o.snapshot = [](const ClashGroup&) -> Result<std::vector<uint8_t>> {
    return Status::IOError("store.mkt: gone");
  };
  w = WriteHtmlReport(run, (dir / "r.html").string(), o);
  ASSERT_FALSE(w.ok());
  EXPECT_EQ(w.status().message(), "store.mkt: gone");
  EXPECT_TRUE(fs::is_empty(dir));
}

// Runs chromium headless on `args`; its stdout, stderr in *err.
std::string Chromium(const std::string& args, std::string* err) {
  const std::string log = ProgramDir().file("chromium.err");
  const std::string cmd =
      "timeout 120 chromium --headless --no-sandbox --disable-gpu --no-first-run "
      "--user-data-dir='" +
      ProgramDir().file("profile") + "' " + args + " 2>'" + log + "'";
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  size_t n;
  while (p && (n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  EXPECT_EQ(p ? pclose(p) : -1, 0) << cmd;
  *err = ReadFileBytes(log);
  return out;
}

TEST(HtmlReport, LoadsInHeadlessChromium) {
  if (!HasProgram("chromium")) GTEST_SKIP() << "chromium is not installed (scripts/setup.sh installs it)";
  const ClashRun run = HandRun();
  HtmlReportOptions o;
  const std::vector<uint8_t> png = SolidPng(600, 200, 225, 25, 25);
  o.snapshot = [&](const ClashGroup&) -> Result<std::vector<uint8_t>> { return png; };
  const std::string path = ProgramDir().file("chromium.html");
  ASSERT_TRUE(WriteHtmlReport(run, path, o).ok());
  const std::string url = "file://" + path;

  // The script ran to its end without an error, nothing was refused or failed to load.
  std::string err;
  const std::string dom = Chromium("--enable-logging=stderr --v=0 --dump-dom '" + url + "'", &err);
  EXPECT_NE(dom.find("data-ready=\"1\""), std::string::npos) << dom.substr(0, 2000);
  EXPECT_EQ(Count(dom, "<section class=\"group"), 3u);
  EXPECT_NE(dom.find("<span id=\"shown\">3</span>"), std::string::npos);
  for (const char* bad : {"Uncaught", "Refused", "ERR_", "CONSOLE"})
    EXPECT_EQ(err.find(bad), std::string::npos) << bad << " in chromium's log:\n" << err;

  // Filters from the URL: one touch group shown, the two others hidden.
  const std::string filtered = Chromium("--dump-dom '" + url + "#class=touch'", &err);
  EXPECT_NE(filtered.find("<span id=\"shown\">1</span>"), std::string::npos);
  EXPECT_EQ(Count(filtered, "hidden=\"\""), 2u);

  // The screenshot shows the page: mostly light, with the hard colour of the snapshots and badges.
  const std::string shot = ProgramDir().file("chromium.png");
  Chromium("--screenshot='" + shot + "' --window-size=1200,1600 '" + url + "'", &err);
  ASSERT_TRUE(fs::exists(shot)) << err;
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&img, shot.c_str()));
  img.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> rgb(PNG_IMAGE_SIZE(img));
  ASSERT_TRUE(png_image_finish_read(&img, nullptr, rgb.data(), 0, nullptr));
  EXPECT_EQ(img.width, 1200u);
  size_t dark = 0, red = 0;
  const size_t pixels = rgb.size() / 3;
  for (size_t i = 0; i < rgb.size(); i += 3) {
    dark += rgb[i] < 100 && rgb[i + 1] < 100 && rgb[i + 2] < 100;  // text
    red += rgb[i] > 200 && rgb[i + 1] < 60 && rgb[i + 2] < 60;
  }
  EXPECT_GT(dark, pixels / 200) << "no text in the screenshot";
  EXPECT_GT(red, pixels / 20) << "no snapshot or hard badge in the screenshot";
  if (const char* keep = std::getenv("MKTREE_KEEP_SCREENSHOT"))
    fs::copy_file(shot, keep, fs::copy_options::overwrite_existing);
}

// The BCF archive and the page of one run render each snapshot once through a memoized source.
TEST(HtmlReport, MemoizedSnapshotsRenderOnce) {
  const ClashRun run = HandRun();
  std::map<std::string, int> calls;
  const std::vector<uint8_t> png = SolidPng(8, 8, 0, 0, 0);
  GroupSnapshotSource counted = [&](const ClashGroup& g) -> Result<std::vector<uint8_t>> {
    ++calls[g.key];
    if (g.worst == ClashClass::kTouch) return Status::IOError("touch: cannot render");
    return png;
  };
  GroupSnapshotSource memo = MemoizedSnapshotSource(counted, 10);
  BcfOptions b;
  b.snapshot = memo;
  b.max_snapshots = 1;  // the first group only
  ASSERT_TRUE(WriteBcf(run, ProgramDir().file("memo.bcf"), b).ok());
  HtmlReportOptions h;
  h.snapshot = memo;
  h.max_snapshots = 1;  // the worst group: the same one
  ASSERT_TRUE(WriteHtmlReport(run, ProgramDir().file("memo.html"), h).ok());
  EXPECT_EQ(calls, (std::map<std::string, int>{{run.groups[0].key, 1}}));
  // Errors are not kept: asked again, the source is asked again.
  EXPECT_FALSE(memo(run.groups[1]).ok());
  EXPECT_FALSE(memo(run.groups[1]).ok());
  EXPECT_EQ(calls[run.groups[1].key], 2);
  // Past max_groups nothing more is kept.
  GroupSnapshotSource one = MemoizedSnapshotSource(counted, 1);
  for (int i = 0; i < 2; ++i) ASSERT_TRUE(one(run.groups[2]).ok() && one(run.groups[0]).ok());
  EXPECT_EQ(calls[run.groups[2].key], 1);
  EXPECT_EQ(calls[run.groups[0].key], 3);
}

}  // namespace
}  // namespace mktree
