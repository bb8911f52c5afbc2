// sim/present/plot_render.cc — running gnuplot on the scripts of `ncosim plot` (sim/present/plot.h,
// render_figures): the .dat and .gp files written atomically, gnuplot run in the folder once per
// figure with the requested formats, its messages passed on.
#include <fcntl.h>
#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string_view>
#include <vector>

#include "config/config.h"
#include "sim/analysis/output.h"
#include "sim/present/plot.h"

namespace ncosim::sim {

namespace fs = std::filesystem;

namespace {

// The environment of gnuplot: ours with LC_ALL=C.UTF-8. The scripts say `set encoding utf8`; under
// a C or POSIX locale (a fresh Debian root, a CI container) gnuplot warns "iconv failed to convert
// degree sign" on every script. C.UTF-8 is built into glibc, and keeps '.' as the decimal point.
std::vector<std::string> gnuplot_environment() {
  std::vector<std::string> env;
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
    if (std::string_view(*e).starts_with("LC_ALL=")) continue;
    env.emplace_back(*e);
  }
  env.emplace_back("LC_ALL=C.UTF-8");
  return env;
}

// Runs `gnuplot -e "formats='...'" NAME.gp` in `dir`; throws with gnuplot's messages on failure
// and passes its warnings on to stderr.
void run_gnuplot(const std::string& dir, const std::string& gp, const std::string& formats) {
  int pipefd[2];
  if (::pipe(pipefd) != 0) throw std::runtime_error(fmt::format("pipe: {}", std::strerror(errno)));
  const std::string expr = fmt::format("formats='{}'", formats);
  // Built before fork: the child may only call async-signal-safe functions.
  std::vector<std::string> env = gnuplot_environment();
  std::vector<char*> envp;
  for (auto& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  std::vector<std::string> args{"gnuplot", "-e", expr, gp};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(fmt::format("fork: {}", std::strerror(errno)));
  if (pid == 0) {
    ::close(pipefd[0]);
    ::dup2(pipefd[1], 2);
    const int devnull = ::open("/dev/null", O_RDWR);
    if (devnull >= 0) {
      ::dup2(devnull, 0);
      ::dup2(devnull, 1);
    }
    if (::chdir(dir.c_str()) != 0) ::_exit(126);
    ::execvpe("gnuplot", argv.data(), envp.data());
    ::_exit(127);
  }
  ::close(pipefd[1]);
  std::string messages;
  char buf[4096];
  for (;;) {
    const ssize_t r = ::read(pipefd[0], buf, sizeof buf);
    if (r > 0) {
      messages.append(buf, static_cast<std::size_t>(r));
    } else if (r == 0 || errno != EINTR) {
      break;
    }
  }
  ::close(pipefd[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    if (WIFEXITED(status) && WEXITSTATUS(status) == 127) {
      throw std::runtime_error("gnuplot not found on PATH (Debian package gnuplot-nox)");
    }
    throw std::runtime_error(fmt::format("gnuplot {} failed in {}:\n{}", gp, dir, messages));
  }
  if (!messages.empty()) std::cerr << fmt::format("gnuplot {}: {}", gp, messages);
}

}  // namespace

std::vector<std::string> render_figures(const std::string& dir, const std::vector<Figure>& figures,
                                        const std::vector<std::string>& formats) {
  std::vector<std::pair<std::string, std::string>> files;
  for (const auto& f : figures) {
    files.emplace_back(f.name + ".dat", f.dat);
    files.emplace_back(f.name + ".gp", f.gp);
  }
  write_files_atomically(dir, files);
  std::string fmts;
  for (const auto& f : formats) {
    if (f != "png" && f != "svg")
      throw config::ScenarioError(fmt::format("--format '{}': expected png or svg", f));
    fmts += (fmts.empty() ? "" : " ") + f;
  }
  std::vector<std::string> images;
  for (const auto& f : figures) {
    run_gnuplot(dir, f.name + ".gp", fmts);
    for (const auto& x : formats) images.push_back((fs::path(dir) / (f.name + "." + x)).string());
  }
  return images;
}

}  // namespace ncosim::sim
