// tests/browser/browser_test.cc — the report of a small campaign opened in headless Chromium
// (Debian `chromium`, no network): it renders with no console message and no failed resource
// load, every figure is present with a non-zero size, every id is unique, the HTML is well-formed
// (xmllint), and a screenshot is saved into the build folder (browser/report_screenshot.png).
// A probe script is injected into a *copy* of the report (the report itself has no script); a
// copy with a broken image must be caught by the same probe (so the check can fail).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

#include "test_util.h"

namespace {

namespace fs = std::filesystem;
const std::string kBinary = NCOSIM_BINARY;
const fs::path kData = fs::path(NCOSIM_SOURCE_DIR) / "tests" / "cli" / "data";
// The build folder: NCOSIM_BINARY is <build>/sim/ncosim.
const fs::path kBuild = fs::path(NCOSIM_BINARY).parent_path().parent_path();

std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// The flags for a machine without network, display or GPU; a fresh profile each call.
std::string chromium(const fs::path& profile, const std::string& args) {
  return fmt::format(
      "timeout 120 chromium --headless {} --disable-gpu --disable-quic --no-first-run "
      "--disable-background-networking "
      "--disable-component-update --disable-sync --disable-extensions --user-data-dir={} {}",
      ::geteuid() == 0 ? "--no-sandbox" : "", shell_quote(profile.string()), args);
}

// Runs before anything else on the page: records errors (script errors and failed loads, which
// do not bubble: capture phase), console messages, and after `load` writes a JSON verdict into
// <pre id="ncosim-probe">.
const char* kProbe = R"(<script>
(function () {
  var problems = [];
  window.addEventListener('error', function (e) {
    var t = e.target;
    problems.push(t && t !== window ? 'failed load: ' + (t.src || t.href || t.tagName) : 'script error: ' + e.message);
  }, true);
  ['error', 'warn', 'log', 'info'].forEach(function (k) {
    var f = console[k];
    console[k] = function () { problems.push('console.' + k + ': ' + Array.prototype.join.call(arguments, ' ')); f.apply(console, arguments); };
  });
  window.addEventListener('load', function () {
    var figs = document.querySelectorAll('figure');
    var sizes = [];
    for (var i = 0; i < figs.length; i++) {
      var s = figs[i].querySelector('svg');
      var r = s ? s.getBoundingClientRect() : {width: 0, height: 0};
      sizes.push([figs[i].id, Math.round(r.width), Math.round(r.height), s ? s.querySelectorAll('path').length : 0]);
    }
    var ids = {}, dups = [];
    var all = document.querySelectorAll('[id]');
    for (var j = 0; j < all.length; j++) { if (ids[all[j].id]) dups.push(all[j].id); ids[all[j].id] = 1; }
    var res = performance.getEntriesByType('resource').map(function (x) { return x.name; });
    var pre = document.createElement('pre');
    pre.id = 'ncosim-probe';
    pre.textContent = JSON.stringify({problems: problems, figures: sizes, duplicate_ids: dups, resources: res,
                                      tables: document.querySelectorAll('table').length});
    document.body.appendChild(pre);
  });
})();
</script>)";

struct Verdict {
  nlohmann::json j;
  std::string stderr_console;  // Chromium's log lines of console messages
  std::string raw;
};

// Measures the layout in a 1280-px-wide window: per figure its SVG's width attribute and
// rendered width and height; the summary table's right edge and its status header's.
const char* kLayoutProbe = R"(<script>
window.addEventListener('load', function () {
  var figs = [];
  document.querySelectorAll('figure svg').forEach(function (s) {
    figs.push([parseFloat(s.getAttribute('width')), Math.round(s.getBoundingClientRect().width),
               parseFloat(s.getAttribute('height'))]);
  });
  var h = document.getElementById('summary'), t = null;
  document.querySelectorAll('table').forEach(function (x) {
    if (!t && (h.compareDocumentPosition(x) & Node.DOCUMENT_POSITION_FOLLOWING)) t = x;
  });
  var status = null;
  if (t) t.querySelectorAll('th').forEach(function (c) { if (c.textContent === 'status') status = c.getBoundingClientRect().right; });
  var pre = document.createElement('pre');
  pre.id = 'ncosim-probe';
  pre.textContent = JSON.stringify({window: window.innerWidth, figures: figs,
                                    table_right: t ? t.getBoundingClientRect().right : null,
                                    status_right: status});
  document.body.appendChild(pre);
});
</script>)";

Verdict probe(const fs::path& html, const fs::path& work, const std::string& extra_body = "",
              const char* script = kProbe, const std::string& flags = "") {
  std::string text = ncosim::testing::read_text(html.string());
  const auto head = text.find("<head>");
  EXPECT_NE(head, std::string::npos);
  text.insert(head + 6, script);
  if (!extra_body.empty()) text.insert(text.find("</body>"), extra_body);
  const fs::path copy = work / fmt::format("{}_probe{}.html", html.stem().string(),
                                           extra_body.empty() ? "" : "_broken");
  {
    std::ofstream o(copy, std::ios::binary);
    o << text;
  }
  const fs::path err = work / "chromium_stderr.txt";
  const auto out = ncosim::testing::run_shell(
      chromium(work / fmt::format("profile{}", extra_body.size()),
               flags + " --enable-logging=stderr --v=0 --virtual-time-budget=5000 --dump-dom " +
                   shell_quote("file://" + copy.string())) +
      " 2>" + shell_quote(err.string()));
  Verdict v;
  v.raw = out.output;
  std::smatch m;
  const std::regex pre(R"re(<pre id="ncosim-probe">([^<]*)</pre>)re");
  if (std::regex_search(out.output, m, pre)) {
    std::string js = m[1].str();
    for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
             {"&quot;", "\""}, {"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}}) {
      for (auto p = js.find(from); p != std::string::npos; p = js.find(from, p + to.size()))
        js.replace(p, from.size(), to);
    }
    v.j = nlohmann::json::parse(js);
  }
  std::istringstream log(ncosim::testing::read_text(err.string()));
  for (std::string line; std::getline(log, line);) {
    if (line.find(":CONSOLE") != std::string::npos) v.stderr_console += line + "\n";
  }
  return v;
}

TEST(Browser, ReportRendersInHeadlessChromium) {
  ASSERT_EQ(ncosim::testing::run_shell("command -v chromium").code, 0)
      << "chromium is not installed (scripts/bootstrap.sh installs it)";
  const fs::path work = kBuild / "browser";
  fs::remove_all(work);
  fs::create_directories(work);
  const fs::path out = work / "campaign";
  auto r = ncosim::testing::run_shell(
      fmt::format("{} run {} --out {} --trace --runs 2 --quiet", shell_quote(kBinary),
                  shell_quote((kData / "plot_names.toml").string()), shell_quote(out.string())));
  ASSERT_EQ(r.code, 0) << r.output;
  r = ncosim::testing::run_shell(
      fmt::format("{} report {}", shell_quote(kBinary), shell_quote(out.string())));
  ASSERT_EQ(r.code, 0) << r.output;
  const fs::path html = out / "report.html";
  const auto lint = ncosim::testing::run_shell("xmllint --noout " + shell_quote(html.string()));
  EXPECT_EQ(lint.code, 0) << "not well-formed: " << lint.output;

  const Verdict v = probe(html, work);
  ASSERT_TRUE(v.j.is_object()) << "no probe result in the DOM dump:\n" << v.raw.substr(0, 2000);
  EXPECT_TRUE(v.j["problems"].empty()) << v.j["problems"].dump();
  EXPECT_TRUE(v.stderr_console.empty()) << v.stderr_console;
  EXPECT_TRUE(v.j["resources"].empty()) << "the report loaded: " << v.j["resources"].dump();
  EXPECT_TRUE(v.j["duplicate_ids"].empty()) << v.j["duplicate_ids"].dump();
  ASSERT_EQ(v.j["figures"].size(), 4u) << v.j.dump();  // mse, mse_ext, paired mse_diff, trace
  for (const auto& f : v.j["figures"]) {
    EXPECT_GT(f[1].get<int>(), 100) << f.dump();  // rendered width, px
    EXPECT_GT(f[2].get<int>(), 100) << f.dump();
    EXPECT_GT(f[3].get<int>(), 5) << f.dump();  // drawn paths
  }
  EXPECT_GE(v.j["tables"].get<int>(), 3);

  // The same probe catches a missing image and a console error.
  const Verdict bad =
      probe(html, work, "<img src=\"missing.png\" alt=\"\"/><script>console.error('x');</script>");
  ASSERT_TRUE(bad.j.is_object());
  EXPECT_EQ(bad.j["problems"].size(), 2u) << bad.j["problems"].dump();

  // Screenshot of the report itself (no probe), for a person to look at.
  const fs::path shot = work / "report_screenshot.png";
  const auto s = ncosim::testing::run_shell(
      chromium(work / "profile_shot",
               fmt::format("--window-size=1280,1600 --screenshot={} {}", shell_quote(shot.string()),
                           shell_quote("file://" + html.string()))) +
      " 2>/dev/null");
  ASSERT_TRUE(fs::exists(shot)) << s.output;
  EXPECT_GT(fs::file_size(shot), 20'000u);
  std::cout << "screenshot: " << shot.string() << "\n";
}

// Issue 40.8, on the pendulum's shape (32 estimators, 20000 periods, an error curve, one row
// whose runs diverge): the one-case figure was 3770 px wide and shrunk until no label could be
// read, the report was 6.5 MB (the error curve drew every period of every estimator), and the
// summary table was wider than 1280 px with `status` behind a scroll. In a 1280-px window every
// figure is drawn at its own width, the summary table and its status fit, and the report stays
// under 1 MB.
TEST(Browser, ManyRowReportFitsTheWindowAndStaysSmall) {
  ASSERT_EQ(ncosim::testing::run_shell("command -v chromium").code, 0)
      << "chromium is not installed (scripts/bootstrap.sh installs it)";
  const fs::path work = kBuild / "browser_many";
  fs::remove_all(work);
  fs::create_directories(work);
  const fs::path out = work / "pendulum";
  const fs::path scenario =
      fs::path(NCOSIM_SOURCE_DIR) / "scenarios" / "schenato2008_pendulum.toml";
  auto r = ncosim::testing::run_shell(
      fmt::format("{} run {} --out {} --runs 2 --no-timing --set run.error_curve=true --quiet",
                  shell_quote(kBinary), shell_quote(scenario.string()), shell_quote(out.string())));
  ASSERT_EQ(r.code, 0) << r.output;
  r = ncosim::testing::run_shell(
      fmt::format("{} report {}", shell_quote(kBinary), shell_quote(out.string())));
  ASSERT_EQ(r.code, 0) << r.output;
  const fs::path html = out / "report.html";
  const auto size = fs::file_size(html);
  std::cout << "32-estimator report: " << size << " bytes; " << r.output;
  EXPECT_LT(size, 1'000'000u);
  const Verdict v = probe(html, work, "", kLayoutProbe, "--window-size=1280,1024");
  ASSERT_TRUE(v.j.is_object()) << "no probe result in the DOM dump:\n" << v.raw.substr(0, 2000);
  std::cout << "layout: " << v.j.dump() << "\n";
  ASSERT_EQ(v.j["window"].get<int>(), 1280) << v.j.dump();
  ASSERT_GE(v.j["figures"].size(), 3u) << v.j.dump();  // mse, mse_diff, error curve
  for (const auto& f : v.j["figures"]) {
    EXPECT_LE(f[0].get<double>(), 1200.0) << f.dump();                     // drawn for the page
    EXPECT_GE(f[1].get<double>(), 0.99 * f[0].get<double>()) << f.dump();  // not shrunk
  }
  // The dot plot grows downwards: 32 rows of 22 px.
  EXPECT_GE(v.j["figures"][0][2].get<double>(), 32 * 22.0) << v.j.dump();
  ASSERT_FALSE(v.j["table_right"].is_null()) << v.j.dump();
  EXPECT_LE(v.j["table_right"].get<double>(), 1280.0) << v.j.dump();
  ASSERT_FALSE(v.j["status_right"].is_null()) << v.j.dump();
  EXPECT_LE(v.j["status_right"].get<double>(), 1280.0) << v.j.dump();
}

}  // namespace
