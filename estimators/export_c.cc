// estimators/export_c.cc — C99 code generation for designed jump observers.
#include "estimators/export_c.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <stdexcept>

#include "kernel/check.h"

namespace ncosim::est {

std::string c_identifier(const std::string& name, std::vector<std::string>& taken) {
  static const std::vector<std::string> keywords{
      "auto",     "break",  "case",   "char",     "const",     "continue", "default",  "do",
      "double",   "else",   "enum",   "extern",   "float",     "for",      "goto",     "if",
      "inline",   "int",    "long",   "register", "restrict",  "return",   "short",    "signed",
      "sizeof",   "static", "struct", "switch",   "typedef",   "union",    "unsigned", "void",
      "volatile", "while",  "_bool",  "_complex", "_imaginary"};
  std::string id;
  for (const char ch : name) {
    const auto u = static_cast<unsigned char>(ch);
    if (std::isalnum(u) != 0 && u < 128) {
      id += static_cast<char>(std::tolower(u));
    } else if (!id.empty() && id.back() != '_') {
      id += '_';
    }
  }
  while (!id.empty() && id.back() == '_') id.pop_back();
  if (id.empty()) id = "jump";
  if (std::isdigit(static_cast<unsigned char>(id[0])) != 0) id = "jump_" + id;
  if (std::find(keywords.begin(), keywords.end(), id) != keywords.end()) id += "_";
  std::string unique = id;
  for (int i = 2; std::find(taken.begin(), taken.end(), unique) != taken.end(); ++i) {
    unique = fmt::format("{}_{}", id, i);
  }
  taken.push_back(unique);
  return unique;
}

namespace {

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string num(double v) { return fmt::format("{:.17g}", v); }

// A C initialiser list of a matrix (rows of `cols` values), indented.
std::string matrix_init(const Eigen::MatrixXd& m, const std::string& indent) {
  std::string out;
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    out += indent + "{";
    for (Eigen::Index c = 0; c < m.cols(); ++c) out += (c ? ", " : "") + num(m(r, c));
    out += r + 1 < m.rows() ? "},\n" : "}\n";
  }
  return out;
}

const char* grouping_name(Grouping g) {
  static const char* names[] = {"S1", "S2", "S3", "S4"};
  return names[static_cast<int>(g)];
}

// The header up to {P}_step: the usage, sizes and state ({P}.h).
constexpr char kHeader[] =
    R"(/* {P}.h — jump observer "{name}" ({grouping}, history Nbar = {Nbar}, max delay dbar = {dbar}),
 * exported by {generator} from {origin}.
 * Dolz, Penarrocha & Sanchis (2014), eqs. (6), (10), (16): self-contained C99, no allocation,
 * no library (not even libm), no global state: every observer instance is a {P}_state.
 *
 * HOW TO USE (once per control period k, period {period} s):
 *   {P}_state s;  {P}_init(&s);                 once, before period 0
 *   every period k = 0, 1, 2, ...:
 *     for every sample that has arrived since the previous step:
 *       {P}_receive(&s, sensor, k - stamp, y);   stamp = period at which the sample was taken,
 *                                                 y = its {ny_note}
 *     {P}_step_input(&s, u);                      u = the input applied during period k-1
 *                                                 (ignored at the first step), or
 *     {P}_step(&s, drive);                        drive = Bu u[k-1] (plus any known input term)
 *     xhat = {P}_estimate(&s);                    xhat[k|k], {U}_N values
 * Samples with delay k - stamp outside 0..{U}_DBAR are discarded ({P}_receive returns 0);
 * a sample received twice in one period keeps the last value. A buffered packet is passed as
 * one {P}_receive per sample it carries, each with its own delay.
 *
 * Sensors (index as in the scenario's [[sensor]] order):
{sensors} *
 * Units: those of the scenario's plant model (states, inputs, outputs); delays and the
 * history N in control periods.
 *
 * Gain selection (exactly as ncosim's jump estimator): N = periods since the last update
 * (1 at the first step), saturated at {U}_NBAR; pattern = bit j set when fictitious sensor
 * j = sensor * ({U}_DBAR + 1) + delay delivered this period; no update when pattern = 0.
 * Gain index = (N - 1) * {U}_GROUPS + group, group = {group_rule}.
 *
 * Memory: gain table {U}_GAINS x {U}_NB x {U}_NMB doubles = {table_bytes} bytes (const, may live
 * in flash); other constant tables {other_bytes} bytes; state sizeof({P}_state) ~ {state_bytes} bytes.
 * Work per step: at most {flops} floating-point operations (the paper's count).
 * Design: predicted tr(Pt) over the extended state {pred_ext}, plant block {pred}.
 */
#ifndef {U}_H_
#define {U}_H_

#define {U}_N {n}        /* plant states */
#define {U}_NU {nu}       /* inputs */
#define {U}_DBAR {dbar}     /* max delay used (periods) */
#define {U}_NB {nb}       /* extended state n (dbar + 1) */
#define {U}_SENSORS {sens}
#define {U}_NF {nf}       /* fictitious sensors: sensors x (dbar + 1) */
#define {U}_NMB {nmb}      /* fictitious output rows */
#define {U}_NBAR {Nbar}     /* history bound Nbar */
#define {U}_GROUPS {groups}   /* gains per N */
#define {U}_GAINS {gains}    /* stored gains = Nbar x groups */

typedef struct {{
  double x[{U}_NB];      /* [xhat[k]; xhat[k-1]; ...; xhat[k-dbar]] */
  double y[{U}_NMB];     /* samples received for this period, fictitious row order */
  unsigned long pattern; /* bit j: fictitious sensor j received this period */
  unsigned int since;    /* periods since the last update, saturated at NBAR */
  int started;           /* 0 before the first step */
}} {P}_state;

/* Initial estimate: the design's xhat0 in every delay block. */
void {P}_init({P}_state *s);
/* Initial estimate xhat0 ({U}_N values) in every delay block. */
void {P}_init_with({P}_state *s, const double *xhat0);
/* Records a sample of `sensor` taken `delay` periods ago; y holds its values (their number
   is in the sensor list above). Returns 1 if it will be used at the next step, 0 if discarded. */
int {P}_receive({P}_state *s, int sensor, int delay, const double *y);
/* One control period: prediction with `drive` ({U}_N values, Bu u[k-1]; skipped at the
   first step), then the correction with the samples received since the previous step. */
void {P}_step({P}_state *s, const double *drive);
)";

// The header after {P}_step (and {P}_step_input when the plant has inputs).
constexpr char kHeaderEnd[] =
    R"(/* xhat[k|k] after the last step: {U}_N values (the first block of s->x). */
const double *{P}_estimate(const {P}_state *s);
/* Gain index for N periods since the last update (saturated at {U}_NBAR) and an availability
   pattern; -1 for pattern 0 (no update). */
int {P}_gain_index(unsigned int N, unsigned long pattern);

#endif /* {U}_H_ */
)";

// One comment line per sensor: its values per sample and its fictitious sensors.
std::string sensor_lines(const ExtendedModel& e) {
  std::string sensors;
  for (int i = 0; i < e.sensors; ++i) {
    const auto& f = e.fict[static_cast<std::size_t>(e.index(i, 0))];
    sensors +=
        fmt::format(" *     sensor {}: {} value(s) per sample, fictitious sensors j = {}..{}\n", i,
                    f.rows, e.index(i, 0), e.index(i, e.dbar));
  }
  return sensors;
}

std::string group_rule(Grouping g) {
  return g == Grouping::kS1   ? std::string("0 (S1: one gain per N)")
         : g == Grouping::kS2 ? std::string("number of real sensors in the pattern - 1 (S2)")
         : g == Grouping::kS3 ? std::string("number of fictitious sensors in the pattern - 1 (S3)")
                              : std::string("pattern - 1 (S4: one gain per pattern)");
}

// Floating-point operations of one step at most (the paper's count).
double step_flops(const ExtendedModel& e) {
  const double nb = static_cast<double>(e.nb), nu = static_cast<double>(e.nu),
               nmb = static_cast<double>(e.nmb);
  return nb * nb + nb * nu + 2 * nb * nmb + 2 * nb + nmb;
}

std::string header(const CExportItem& it, const std::string& generator) {
  const ExtendedModel& e = it.jump->extended_model();
  const JumpDesign& d = it.jump->jump_design();
  const std::string P = it.prefix, U = upper(it.prefix);
  const long gains = static_cast<long>(d.gains.size());
  const long table_bytes = gains * static_cast<long>(e.nb * e.nmb) * 8;
  const long other_bytes = static_cast<long>(e.n * e.n + e.n * e.nu + e.nmb * e.n + e.n) * 8 +
                           static_cast<long>(e.nmb) * 2 * 2;
  std::string h = fmt::format(
      kHeader, fmt::arg("P", P), fmt::arg("U", U), fmt::arg("name", it.name),
      fmt::arg("grouping", grouping_name(d.grouping)), fmt::arg("Nbar", d.Nbar),
      fmt::arg("dbar", e.dbar), fmt::arg("generator", generator), fmt::arg("origin", it.origin),
      fmt::arg("period", it.period), fmt::arg("ny_note", "values (the sensor's outputs, in order)"),
      fmt::arg("sensors", sensor_lines(e)), fmt::arg("group_rule", group_rule(d.grouping)),
      fmt::arg("table_bytes", table_bytes), fmt::arg("other_bytes", other_bytes),
      fmt::arg("state_bytes", (e.nb + e.nmb) * 8 + 16), fmt::arg("flops", step_flops(e)),
      fmt::arg("pred_ext", d.stable ? num(d.Pt.trace()) : "none"),
      fmt::arg("pred", d.stable ? num(d.Pt.topLeftCorner(e.n, e.n).trace()) : "none"),
      fmt::arg("n", e.n), fmt::arg("nu", e.nu), fmt::arg("nb", e.nb), fmt::arg("sens", e.sensors),
      fmt::arg("nf", e.fictitious_count()), fmt::arg("nmb", e.nmb),
      fmt::arg("groups", groups_per_N(d.grouping, e)), fmt::arg("gains", gains));
  if (e.nu > 0) {
    h += fmt::format(
        "/* As {P}_step with drive = Bu u ({U}_NU values of u[k-1]). */\n"
        "void {P}_step_input({P}_state *s, const double *u);\n",
        fmt::arg("P", P), fmt::arg("U", U));
  }
  h += fmt::format(kHeaderEnd, fmt::arg("P", P), fmt::arg("U", U));
  return h;
}

// The source's start: the plant's A ({P}.c).
constexpr char kSourceHead[] =
    R"(/* {P}.c — see {P}.h. Generated: edit the scenario and re-export instead. */
#include "{P}.h"

/* Plant A (n x n): the first block of Abar. */
static const double {P}_a[{U}_N][{U}_N] = {{
{a}}};
)";

// The fictitious rows' tables, xhat0, and the gain table's opening.
constexpr char kSourceTables[] =
    R"(/* Per fictitious output row: the sensor's C row, the delay block it reads, its fictitious sensor. */
static const double {P}_crow[{U}_NMB][{U}_N] = {{
{c}}};
static const unsigned char {P}_row_delay[{U}_NMB] = {{{rd}}};
static const unsigned char {P}_row_fict[{U}_NMB] = {{{rf}}};
/* Per fictitious sensor j: first row, number of rows. */
static const unsigned short {P}_fict_row[{U}_NF] = {{{fr}}};
static const unsigned short {P}_fict_rows[{U}_NF] = {{{frs}}};
/* Initial estimate of the design (plant state). */
static const double {P}_xhat0[{U}_N] = {{{x0}}};

/* Gains L[index][extended state][fictitious row]. */
static const double {P}_gain[{U}_GAINS][{U}_NB][{U}_NMB] = {{
)";

// The functions (eqs. (6), (10)), after the gain table and the group rule.
constexpr char kSourceFunctions[] = R"(int {P}_gain_index(unsigned int N, unsigned long pattern) {{
  int group;
  if (pattern == 0UL || pattern >= (1UL << {U}_NF)) return -1;
  if (N < 1U) N = 1U;
  if (N > {U}_NBAR) N = {U}_NBAR;
{group}  return (int)(N - 1U) * {U}_GROUPS + group;
}}

void {P}_init_with({P}_state *s, const double *xhat0) {{
  int b, i;
  for (b = 0; b <= {U}_DBAR; ++b) {{
    for (i = 0; i < {U}_N; ++i) s->x[b * {U}_N + i] = xhat0[i];
  }}
  for (i = 0; i < {U}_NMB; ++i) s->y[i] = 0.0;
  s->pattern = 0UL;
  s->since = 0U;
  s->started = 0;
}}

void {P}_init({P}_state *s) {{ {P}_init_with(s, {P}_xhat0); }}

int {P}_receive({P}_state *s, int sensor, int delay, const double *y) {{
  int j, r;
  if (sensor < 0 || sensor >= {U}_SENSORS || delay < 0 || delay > {U}_DBAR) return 0;
  j = sensor * ({U}_DBAR + 1) + delay;
  for (r = 0; r < {P}_fict_rows[j]; ++r) s->y[{P}_fict_row[j] + r] = y[r];
  s->pattern |= 1UL << j;
  return 1;
}}

void {P}_step({P}_state *s, const double *drive) {{
  int i, r, c, b;
  if (s->started) {{ /* eq. (6): xhat[k-] = Abar xhat[k-1] + Bbar_u u[k-1] */
    double head[{U}_N];
    for (i = 0; i < {U}_N; ++i) {{
      double acc = 0.0;
      for (c = 0; c < {U}_N; ++c) acc += {P}_a[i][c] * s->x[c];
      head[i] = acc;
    }}
    for (b = {U}_DBAR; b >= 1; --b) {{
      for (i = 0; i < {U}_N; ++i) s->x[b * {U}_N + i] = s->x[(b - 1) * {U}_N + i];
    }}
    for (i = 0; i < {U}_N; ++i) s->x[i] = head[i] + drive[i];
  }}
  s->started = 1;
  if (s->since < {U}_NBAR) ++s->since;
  if (s->pattern != 0UL) {{ /* eq. (10): xhat += L alpha (mbar - Cbar xhat) */
    double innov[{U}_NMB];
    const double (*L)[{U}_NMB] = {P}_gain[{P}_gain_index(s->since, s->pattern)];
    for (r = 0; r < {U}_NMB; ++r) {{
      if ((s->pattern >> {P}_row_fict[r]) & 1UL) {{
        const double *xb = &s->x[{P}_row_delay[r] * {U}_N];
        double acc = 0.0;
        for (c = 0; c < {U}_N; ++c) acc += {P}_crow[r][c] * xb[c];
        innov[r] = s->y[r] - acc;
      }} else {{
        innov[r] = 0.0;
      }}
    }}
    for (i = 0; i < {U}_NB; ++i) {{
      double acc = 0.0;
      for (r = 0; r < {U}_NMB; ++r) acc += L[i][r] * innov[r];
      s->x[i] += acc;
    }}
    s->since = 0U;
  }}
  s->pattern = 0UL;
}}

const double *{P}_estimate(const {P}_state *s) {{ return s->x; }}
)";

// {P}_step_input, when the plant has inputs.
constexpr char kSourceStepInput[] = R"(
void {P}_step_input({P}_state *s, const double *u) {{
  double drive[{U}_N];
  int i, c;
  for (i = 0; i < {U}_N; ++i) {{
    double acc = 0.0;
    for (c = 0; c < {U}_NU; ++c) acc += {P}_bu[i][c] * u[c];
    drive[i] = acc;
  }}
  {P}_step(s, drive);
}}
)";

std::string int_list(const std::vector<int>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(v[i]);
  return s;
}

// Per fictitious output row: the plant-output row it measures, its delay block, its sensor j.
struct FictitiousRows {
  Eigen::MatrixXd crow;
  std::vector<int> delay, fict;
};
FictitiousRows fictitious_rows(const ExtendedModel& e) {
  const Eigen::Index n = e.n;
  FictitiousRows t{Eigen::MatrixXd(e.nmb, n), std::vector<int>(static_cast<std::size_t>(e.nmb)),
                   std::vector<int>(static_cast<std::size_t>(e.nmb))};
  for (int j = 0; j < e.fictitious_count(); ++j) {
    const auto& f = e.fict[static_cast<std::size_t>(j)];
    for (Eigen::Index r = 0; r < f.rows; ++r) {
      t.crow.row(f.row + r) = e.C.block(f.row + r, f.delay * n, 1, n);
      t.delay[static_cast<std::size_t>(f.row + r)] = f.delay;
      t.fict[static_cast<std::size_t>(f.row + r)] = j;
    }
  }
  return t;
}

// The fictitious-row tables, xhat0 and the gains.
std::string source_tables(const CExportItem& it, const std::string& P, const std::string& U) {
  const ExtendedModel& e = it.jump->extended_model();
  const JumpDesign& d = it.jump->jump_design();
  const FictitiousRows rows = fictitious_rows(e);
  std::vector<int> fict_row, fict_rows;
  for (const auto& f : e.fict) {
    fict_row.push_back(static_cast<int>(f.row));
    fict_rows.push_back(static_cast<int>(f.rows));
  }
  std::string x0;
  const Eigen::VectorXd& v = it.jump->initial_estimate().xhat0;
  for (Eigen::Index i = 0; i < v.size(); ++i) x0 += (i ? ", " : "") + num(v(i));
  std::string s =
      fmt::format(kSourceTables, fmt::arg("P", P), fmt::arg("U", U),
                  fmt::arg("c", matrix_init(rows.crow, "  ")), fmt::arg("rd", int_list(rows.delay)),
                  fmt::arg("rf", int_list(rows.fict)), fmt::arg("fr", int_list(fict_row)),
                  fmt::arg("frs", int_list(fict_rows)), fmt::arg("x0", x0));
  for (std::size_t g = 0; g < d.gains.size(); ++g) {
    s += fmt::format("  {{ /* {} */\n{}  }}{}\n", g, matrix_init(d.gains[g], "    "),
                     g + 1 < d.gains.size() ? "," : "");
  }
  s += "};\n\n";
  return s;
}

// The group rule in C, as group_of() in estimators/design/jump_design.cc.
std::string group_code(Grouping grouping, const std::string& U) {
  switch (grouping) {
    case Grouping::kS1:
      return "  group = 0;\n";
    case Grouping::kS2:
      return fmt::format(
          "  {{\n    int i, count = 0;\n    for (i = 0; i < {U}_SENSORS; ++i) {{\n"
          "      if ((pattern >> (i * ({U}_DBAR + 1))) & ((1UL << ({U}_DBAR + 1)) - 1UL)) "
          "++count;\n    }}\n"
          "    group = count - 1;\n  }}\n",
          fmt::arg("U", U));
    case Grouping::kS3:
      return "  {\n    unsigned long m = pattern;\n    int count = 0;\n    while (m) {\n      m &= "
             "m "
             "- 1UL;\n"
             "      ++count;\n    }\n    group = count - 1;\n  }\n";
    case Grouping::kS4:
      return "  group = (int)pattern - 1;\n";
  }
  return "";
}

std::string source(const CExportItem& it) {
  const ExtendedModel& e = it.jump->extended_model();
  const JumpDesign& d = it.jump->jump_design();
  const std::string P = it.prefix, U = upper(it.prefix);
  std::string s = fmt::format(kSourceHead, fmt::arg("P", P), fmt::arg("U", U),
                              fmt::arg("a", matrix_init(it.plant->A, "  ")));
  if (e.nu > 0) {
    s += fmt::format(
        "/* Plant Bu (n x nu). */\nstatic const double {P}_bu[{U}_N][{U}_NU] = {{\n{b}}};\n",
        fmt::arg("P", P), fmt::arg("U", U), fmt::arg("b", matrix_init(it.plant->Bu, "  ")));
  }
  s += source_tables(it, P, U);
  s += fmt::format(kSourceFunctions, fmt::arg("P", P), fmt::arg("U", U),
                   fmt::arg("group", group_code(d.grouping, U)));
  if (e.nu > 0) s += fmt::format(kSourceStepInput, fmt::arg("P", P), fmt::arg("U", U));
  return s;
}

}  // namespace

std::vector<std::pair<std::string, std::string>> export_c(const std::vector<CExportItem>& items,
                                                          const std::string& generator) {
  std::vector<std::pair<std::string, std::string>> files;
  for (const CExportItem& it : items) {
    const JumpDesign& d = it.jump->jump_design();
    const ExtendedModel& e = it.jump->extended_model();
    if (!d.stable) {
      throw std::invalid_argument(
          fmt::format("estimator \"{}\": the design failed ({}); there are no gains to export",
                      it.name, d.status));
    }
    // The C selection rule must agree with the table JumpObserver uses.
    const int per_N = groups_per_N(d.grouping, e);
    for (int N = 1; N <= d.Nbar; ++N) {
      for (std::size_t m = 1; m < d.gain_of[static_cast<std::size_t>(N - 1)].size(); ++m) {
        NCOSIM_CHECK(d.gain_of[static_cast<std::size_t>(N - 1)][m] ==
                     (N - 1) * per_N + group_of(d.grouping, e, m));
      }
    }
    files.emplace_back(it.prefix + ".h", header(it, generator));
    files.emplace_back(it.prefix + ".c", source(it));
  }
  return files;
}

}  // namespace ncosim::est
