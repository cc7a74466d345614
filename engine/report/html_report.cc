#include "engine/report/html_report.h"

#include <algorithm>
#include <filesystem>
#include <numeric>
#include <set>
#include <string_view>
#include <vector>

#include "engine/report/report_text.h"
#include "storage/atomic_file.h"

namespace mktree {

namespace {

std::string Esc(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
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
        out += "&#39;";
        break;
      default:
        out.push_back(c);
    }
  }
  return out;
}

std::string Base64(const std::vector<uint8_t>& b) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((b.size() + 2) / 3 * 4);
  for (size_t i = 0; i < b.size(); i += 3) {
    const uint32_t v = uint32_t{b[i]} << 16 | (i + 1 < b.size() ? uint32_t{b[i + 1]} << 8 : 0) |
                       (i + 2 < b.size() ? uint32_t{b[i + 2]} : 0);
    out.push_back(kAlphabet[v >> 18]);
    out.push_back(kAlphabet[v >> 12 & 63]);
    out.push_back(i + 1 < b.size() ? kAlphabet[v >> 6 & 63] : '=');
    out.push_back(i + 2 < b.size() ? kAlphabet[v & 63] : '=');
  }
  return out;
}

std::string Lower(std::string_view s) {
  std::string out(s);
  for (char& c : out)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return out;
}

std::string StatusWord(ClashStatus s) { return s == ClashStatus::kNone ? "none" : ClashStatusName(s); }

std::string N(uint64_t v) { return std::to_string(v); }

constexpr std::string_view kStyle = R"(<style>
body{font:14px/1.4 system-ui,sans-serif;margin:0 24px 40px;color:#222;background:#fafafa}
h1{font-size:22px;margin:18px 0 4px}h2{font-size:17px;margin:22px 0 8px}
table{border-collapse:collapse;background:#fff;margin:6px 0}
th,td{border:1px solid #ddd;padding:3px 7px;text-align:left;vertical-align:top}
th{background:#f0f0f0}td.n{text-align:right}
.cls{display:inline-block;padding:1px 7px;border-radius:3px;font-weight:600;color:#fff}
.hard{background:#e11919}.touch{background:#fa8200}.clearance{background:#c9a800}
.st{display:inline-block;padding:1px 6px;border-radius:3px;border:1px solid #888;font-size:12px}
.st-new{background:#ffe0e0}.st-active{background:#fff4cc}.st-resolved{background:#dff5df}
.filters{position:sticky;top:0;background:#fafafa;padding:8px 0;border-bottom:1px solid #ccc;z-index:1}
.filters label{margin-right:14px}
section.group{background:#fff;border:1px solid #ccc;border-left:6px solid #999;margin:12px 0;padding:8px 12px}
section.group.hard{border-left-color:#e11919}section.group.touch{border-left-color:#fa8200}
section.group.clearance{border-left-color:#c9a800}
section.group h3{font-size:15px;margin:2px 0 6px}
section.group img{max-width:100%;height:auto;border:1px solid #ddd;display:block;margin:6px 0}
.muted{color:#666}.gid{font-family:monospace;font-size:12px}
</style>
)";

constexpr std::string_view kScript = R"(<script>
(function () {
  var groups = Array.prototype.slice.call(document.querySelectorAll('section.group'));
  var test = document.getElementById('f-test'), cls = document.getElementById('f-class');
  var st = document.getElementById('f-status'), text = document.getElementById('f-text');
  var shown = document.getElementById('shown');
  function apply() {
    var q = text.value.toLowerCase(), n = 0;
    groups.forEach(function (g) {
      var ok = (!test.value || g.dataset.test === test.value) && (!cls.value || g.dataset.cls === cls.value) &&
               (!st.value || g.dataset.status === st.value) && (!q || g.dataset.text.indexOf(q) >= 0);
      g.hidden = !ok;
      if (ok) n++;
    });
    shown.textContent = String(n);
  }
  // A link may carry filters: report.html#class=hard&status=new&test=NAME&text=WORDS
  location.hash.replace(/^#/, '').split('&').forEach(function (kv) {
    var i = kv.indexOf('='), k = kv.slice(0, i), v = decodeURIComponent(kv.slice(i + 1));
    var e = {test: test, 'class': cls, status: st, text: text}[k];
    if (i > 0 && e) e.value = v;
  });
  [test, cls, st].forEach(function (e) { e.addEventListener('change', apply); });
  text.addEventListener('input', apply);
  apply();
  document.body.setAttribute('data-ready', '1');
})();
</script>
)";

// Groups worst first: class, then the most negative distance (deepest overlap, smallest gap), then key.
std::vector<size_t> WorstFirst(const ClashRun& run) {
  std::vector<size_t> order(run.groups.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) {
    const ClashGroup &a = run.groups[x], &b = run.groups[y];
    if (a.worst != b.worst) return report::ClassRank(a.worst) < report::ClassRank(b.worst);
    if (a.worst_distance != b.worst_distance) return a.worst_distance < b.worst_distance;
    return a.key < b.key;
  });
  return order;
}

std::string ObjectCell(const ObjectIdentity& o) {
  std::string s = Esc(o.name.empty() ? "object " + N(o.id) : o.name);
  if (!o.ifc_type.empty()) s += "<br><span class=\"muted\">" + Esc(o.ifc_type) + "</span>";
  if (!o.global_id.empty()) s += "<br><span class=\"gid\">" + Esc(o.global_id) + "</span>";
  return s;
}

std::string RunSummary(const ClashRun& run, const std::string& title) {
  uint64_t by_class[3] = {0, 0, 0}, by_status[4] = {0, 0, 0, 0}, clashes = 0;
  for (const ClashGroup& g : run.groups)
    for (const ClashRecord& r : g.members) {
      ++by_class[report::ClassRank(r.pair.cls)];
      ++by_status[static_cast<int>(r.status)];
      ++clashes;
    }
  std::string h =
      "<h1>" + Esc(title) + "</h1>\n<p class=\"muted\">Store " + Esc(run.store) + ", revision " +
      N(run.revision) +
      ".</p>\n<table><tr><th>groups</th><th>clashes</th><th>hard</th><th>touch</th>"
      "<th>clearance</th><th>new</th><th>active</th><th>resolved</th></tr>\n<tr><td class=\"n\">" +
      N(run.groups.size()) + "</td><td class=\"n\">" + N(clashes) + "</td>";
  for (uint64_t v : by_class) h += "<td class=\"n\">" + N(v) + "</td>";
  for (int s = 1; s < 4; ++s) h += "<td class=\"n\">" + N(by_status[s]) + "</td>";
  return h + "</tr></table>\n";
}

std::string TestsTable(const ClashRun& run) {
  std::string h =
      "<h2>Clash tests</h2>\n<table id=\"tests\"><tr><th>test</th><th>mode</th><th>clearance</th><th>touch "
      "tolerance</th><th>selected A</th><th>selected B</th><th>hard</th><th>touch</th><th>clearance</th>"
      "<th>new</th><th>active</th><th>resolved</th><th>excluded by rule</th><th>warnings</th></tr>\n";
  for (const ClashTestSummary& t : run.tests) {
    h += "<tr><td>" + Esc(t.name) + "</td><td>" + Esc(t.mode) + "</td><td class=\"n\">" +
         report::ShortNumber(t.clearance) + "</td><td class=\"n\">" + report::ShortNumber(t.touch_tolerance) +
         "</td>";
    for (uint64_t v : {t.selected_a, t.selected_b, t.hard, t.touch, t.clearance_pairs, t.new_clashes,
                       t.active, t.resolved})
      h += "<td class=\"n\">" + N(v) + "</td>";
    h += "<td>";
    for (const auto& [rule, n] : t.excluded_by_rule) h += Esc(rule) + ": " + N(n) + "<br>";
    h += "</td><td>";
    for (const std::string& w : t.warnings) h += Esc(w) + "<br>";
    h += "</td></tr>\n";
  }
  return h + "</table>\n";
}

std::string Filters(const ClashRun& run, uint64_t listed) {
  std::set<std::string> tests;
  for (const ClashTestSummary& t : run.tests) tests.insert(t.name);
  for (const ClashGroup& g : run.groups) tests.insert(g.test);
  std::string h = "<div class=\"filters\"><label>Test <select id=\"f-test\"><option value=\"\">all</option>";
  for (const std::string& t : tests) h += "<option value=\"" + Esc(t) + "\">" + Esc(t) + "</option>";
  h += "</select></label><label>Class <select id=\"f-class\"><option "
       "value=\"\">all</option><option>hard</option>"
       "<option>touch</option><option>clearance</option></select></label><label>Status <select "
       "id=\"f-status\">"
       "<option value=\"\">all</option><option>new</option><option>active</option><option>resolved</option>"
       "<option value=\"none\">not compared</option></select></label><label>Text <input id=\"f-text\" "
       "type=\"search\" placeholder=\"name, type, GlobalId\"></label> <span id=\"shown\">" +
       N(listed) + "</span> of " + N(listed) + " groups shown</div>\n";
  return h;
}

std::string GroupHtml(const ClashGroup& g, size_t rank, const std::string& png_base64, uint32_t members,
                      uint64_t* listed) {
  const std::string cls = ClashClassName(g.worst);
  std::string text = Lower(g.title + " " + g.test + " " + g.key);
  std::string rows;
  size_t n = 0;
  for (const ClashRecord& r : g.members) {
    if (n == members) break;
    ++n;
    for (const std::string* f :
         {&r.a->name, &r.a->ifc_type, &r.a->global_id, &r.b->name, &r.b->ifc_type, &r.b->global_id}) {
      text.push_back(' ');
      text += Lower(*f);
    }
    rows += "<tr><td class=\"n\">" + N(n) + "</td><td><span class=\"cls " +
            std::string(ClashClassName(r.pair.cls)) + "\">" + ClashClassName(r.pair.cls) +
            "</span></td><td>" + Esc(report::DepthOrGap(r.pair)) + "</td><td>" + ObjectCell(*r.a) +
            "</td><td>" + ObjectCell(*r.b) + "</td><td>" + Esc(ClashStatusName(r.status)) + "</td></tr>\n";
  }
  *listed = n;
  std::string worst_text;
  if (const ClashRecord* worst = report::WorstMember(g))
    worst_text = "worst " + report::DepthOrGap(worst->pair);
  std::string h = "<section class=\"group " + cls + "\" data-test=\"" + Esc(g.test) + "\" data-cls=\"" + cls +
                  "\" data-status=\"" + StatusWord(g.status) + "\" data-text=\"" + Esc(text) + "\">\n<h3>" +
                  N(rank) + ". " + Esc(g.title.empty() ? g.key : g.title) + "</h3>\n<p><span class=\"cls " +
                  cls + "\">" + cls + "</span> " + Esc(worst_text) + " &middot; " + N(g.members.size()) +
                  (g.members.size() == 1 ? " clash" : " clashes") + " &middot; test " + Esc(g.test);
  if (g.status != ClashStatus::kNone)
    h += " &middot; <span class=\"st st-" + StatusWord(g.status) + "\">" + StatusWord(g.status) + "</span>";
  h += "<br><span class=\"muted gid\">key " + Esc(g.key) + "</span></p>\n";
  if (!png_base64.empty())
    h += "<img alt=\"snapshot of group " + N(rank) + "\" src=\"data:image/png;base64," + png_base64 + "\">\n";
  h += "<table><tr><th>#</th><th>class</th><th>depth or gap</th><th>object A</th><th>object B</th><th>status"
       "</th></tr>\n" +
       rows + "</table>\n";
  if (g.members.size() > n)
    h += "<p class=\"muted\">and " + N(g.members.size() - n) + " more clashes not listed (the page lists " +
         N(n) + " per group).</p>\n";
  return h + "</section>\n";
}

}  // namespace

Result<HtmlReportSummary> WriteHtmlReport(const ClashRun& run, const std::string& path,
                                          const HtmlReportOptions& o) {
  MKTREE_ASSIGN_OR_RETURN(auto out, AtomicFile::Create(path));
  std::string title = o.title;
  if (title.empty()) title = "Clash report: " + std::filesystem::path(run.store).filename().string();
  HtmlReportSummary summary;
  const std::vector<size_t> order = WorstFirst(run);
  const uint64_t listed = std::min<uint64_t>(order.size(), o.max_groups);
  std::string head =
      "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<meta "
      "http-equiv=\"Content-Security-"
      "Policy\" content=\"default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src "
      "'unsafe-inline'\">\n<meta name=\"viewport\" content=\"width=device-width, "
      "initial-scale=1\">\n<title>" +
      Esc(title) + "</title>\n" + std::string(kStyle) + "</head><body>\n" + RunSummary(run, title) +
      TestsTable(run) + "<h2>Groups, worst first</h2>\n" + Filters(run, listed);
  if (listed < order.size())
    head += "<p class=\"muted\">The first " + N(listed) + " of " + N(order.size()) +
            " groups are listed; the rest are left out of this page (they are in the BCF and JSON "
            "outputs).</p>\n";
  MKTREE_RETURN_IF_ERROR(out->Write(head.data(), head.size()));
  for (uint64_t i = 0; i < listed; ++i) {
    const ClashGroup& g = run.groups[order[i]];
    std::string png;
    if (o.snapshot && i < o.max_snapshots) {
      auto bytes = o.snapshot(g);
      if (!bytes.ok()) return bytes.status();
      png = Base64(*bytes);
      ++summary.snapshots;
    }
    uint64_t members = 0;
    const std::string h = GroupHtml(g, i + 1, png, o.members_per_group, &members);
    summary.members_listed += members;
    summary.members_left_out += g.members.size() - members;
    MKTREE_RETURN_IF_ERROR(out->Write(h.data(), h.size()));
  }
  summary.groups_listed = listed;
  summary.groups_left_out = order.size() - listed;
  for (uint64_t i = listed; i < order.size(); ++i)
    summary.members_left_out += run.groups[order[i]].members.size();
  const std::string tail =
      "<p class=\"muted\">Written by mktree. Depths and gaps are in the store's units.</p>\n" +
      std::string(kScript) + "</body></html>\n";
  MKTREE_RETURN_IF_ERROR(out->Write(tail.data(), tail.size()));
  summary.bytes = out->size();
  MKTREE_RETURN_IF_ERROR(out->Commit());
  return summary;
}

}  // namespace mktree
