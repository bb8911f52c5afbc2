// tests/cli/temp_dir_test.h — the fixture the CLI tests share: each test gets a fresh temporary
// folder (removed afterwards) to write scenarios into and point --out at.
#pragma once

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

namespace ncosim::testing {

class TempDirTest : public ::testing::Test {
 protected:
  // The folder is <tmp>/<prefix>XXXXXX (mkdtemp).
  explicit TempDirTest(std::string prefix) : prefix_(std::move(prefix)) {}
  void SetUp() override {
    std::string tmpl = (std::filesystem::temp_directory_path() / (prefix_ + "XXXXXX")).string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  // Writes `text` (bytes as given) to the file `name` in the folder and returns its path.
  std::string write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name, std::ios::binary) << text;
    return (dir_ / name).string();
  }
  std::filesystem::path dir_;

 private:
  std::string prefix_;
};

}  // namespace ncosim::testing
