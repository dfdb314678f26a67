#pragma once
// Running the lambert CLI from tests: exit status and output, and a fixture with a fresh temporary directory.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace lambert::test {

namespace fs = std::filesystem;

struct CliRun {
  int status;
  std::string output;  // stdout and stderr together
};

inline CliRun run(const std::string& args) {
  const std::string cmd = std::string(LAMBERT_BINARY) + " " + args + " 2>&1";
  CliRun r{0, {}};
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return {-1, "popen failed"};
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device rd;
    dir = fs::temp_directory_path() / ("lambert_cli_" + std::to_string(rd()));
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string path(const std::string& name) const { return (dir / name).string(); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path(name)) << text;
    return path(name);
  }
  // Files in dir other than the given ones (temporaries left behind, partial outputs).
  std::vector<std::string> files() const {
    std::vector<std::string> v;
    for (auto& e : fs::directory_iterator(dir)) v.push_back(e.path().filename().string());
    return v;
  }
  fs::path dir;
};

// The lines i,j,F_ij of a `lambert formfactors` output file, by (i, j); lines that are not three numbers are skipped.
inline std::map<std::pair<int, int>, double> read_form_factors(const std::string& path) {
  std::map<std::pair<int, int>, double> m;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    int i = 0, j = 0;
    double f = 0;
    if (std::sscanf(line.c_str(), "%d,%d,%lf", &i, &j, &f) == 3) m[{i, j}] = f;
  }
  return m;
}

}  // namespace lambert::test
