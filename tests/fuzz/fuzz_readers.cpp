// Mutation fuzzer for the scene readers (OBJ + MTL, PLY, OFF, materials JSON), followed by mesh
// preparation and scene building: every input must end in a scene or in lambert::InputError. Anything
// else (another exception, a crash, a sanitizer report, an input taking longer than --max-seconds-per-input)
// is a finding: the input is saved as fuzz-finding-* in the working directory and the program exits 1.
//
//   fuzz_readers CORPUS_DIR [--runs N] [--seed S] [--max-seconds-per-input T] [--replay DIR]
//
// CORPUS_DIR holds obj/, ply/, off/, json/ seed files (tests/fuzz/corpus). Each run picks a seed, stacks 1-4
// mutations (bit flips, deletions, insertions of hostile tokens such as 1e400, nan, 2147483647, 4294967295,
// duplicated lines, truncation, a number token replaced by a hostile one) and reads the result. --replay
// reads every file of DIR once, unmutated (the committed reproducers of issue 15). Deterministic for a
// given seed. Prints, per reader, runs, inputs rejected with InputError and inputs accepted.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "lambert/io/readers.hpp"
#include "lambert/mesh/prepare.hpp"
#include "lambert/mesh/types.hpp"

namespace fs = std::filesystem;
using namespace lambert;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void put(const fs::path& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }

const std::vector<std::string> kTokens = {" 1e400",  " -1e400",    " nan",       " inf",     " -1",   " 0",
                                          " 2147483647", " -2147483648", " 4294967295", " 1e-320", "\n", "\r\n",
                                          "\\\n",    "#",          "/",          "//",        " 3",   " 65535",
                                          "{",       "}",          "[",          "]",         ",",    "\"",
                                          " 1e308",  " 9223372036854775807", "\0", "\xEF\xBB\xBF"};

class Mutator {
 public:
  explicit Mutator(unsigned seed) : rng_(seed) {}
  std::string mutate(std::string s) {
    const int n = 1 + int(rng_() % 4);
    for (int k = 0; k < n; ++k) one(s);
    return s;
  }

 private:
  size_t pos(const std::string& s) { return s.empty() ? 0 : rng_() % (s.size() + 1); }
  void one(std::string& s) {
    switch (rng_() % 7) {
      case 0:  // flip a bit
        if (!s.empty()) s[rng_() % s.size()] ^= char(1u << (rng_() % 8));
        break;
      case 1: {  // delete a range
        const size_t p = pos(s);
        s.erase(p, std::min<size_t>(1 + rng_() % 16, s.size() - p));
        break;
      }
      case 2:  // insert a hostile token
        s.insert(pos(s), kTokens[rng_() % kTokens.size()]);
        break;
      case 3: {  // duplicate a run of lines
        const size_t a = s.rfind('\n', pos(s));
        const size_t start = a == std::string::npos ? 0 : a + 1;
        size_t end = start;
        for (int l = 0, lines = 1 + int(rng_() % 4); l < lines && end < s.size(); ++l) {
          const size_t e = s.find('\n', end);
          end = e == std::string::npos ? s.size() : e + 1;
        }
        const std::string chunk = s.substr(start, end - start);
        for (int r = 0, times = 1 + int(rng_() % 8); r < times; ++r) s.insert(end, chunk);
        break;
      }
      case 4:  // truncate
        s.resize(pos(s));
        break;
      case 5: {  // replace a number token with a hostile one
        std::vector<size_t> starts;
        for (size_t i = 0; i < s.size(); ++i)
          if ((s[i] >= '0' && s[i] <= '9') && (i == 0 || s[i - 1] == ' ' || s[i - 1] == '\n' || s[i - 1] == '[')) starts.push_back(i);
        if (starts.empty()) break;
        const size_t i = starts[rng_() % starts.size()];
        size_t j = i;
        while (j < s.size() && s[j] != ' ' && s[j] != '\n' && s[j] != ',' && s[j] != ']') ++j;
        std::string t = kTokens[rng_() % 12];
        if (!t.empty() && t[0] == ' ') t.erase(0, 1);
        s.replace(i, j - i, t);
        break;
      }
      case 6:  // random bytes
        for (int r = 0, m = 1 + int(rng_() % 8); r < m; ++r) s.insert(pos(s), 1, char(rng_() % 256));
        break;
    }
  }
  std::mt19937 rng_;
};

struct Counts {
  long runs = 0, rejected = 0, accepted = 0;
};

enum class Outcome { accepted, rejected, finding };

// Reads `file` as `kind`, prepares and builds the scene. Returns the outcome; prints a finding.
Outcome exercise(const std::string& kind, const fs::path& file, const fs::path& scene_for_json, double max_seconds,
                 std::string& why) {
  const auto t0 = std::chrono::steady_clock::now();
  try {
    mesh::PolygonSoup soup;
    if (kind == "json") {
      soup = io::read_obj(scene_for_json.string());
      io::apply_materials_json(soup, file.string());
    } else {
      soup = io::read_soup(file.string());
    }
    mesh::PrepareOptions prep;
    prep.max_patches = 20000;
    if (soup.faces.size() < 50) prep.max_edge = 0.5;  // refinement too, on small scenes
    mesh::Scene scene = mesh::prepare_and_build(soup, prep);
    (void)scene;
  } catch (const InputError&) {
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (s > max_seconds) {
      why = "rejected, but took " + std::to_string(s) + " s";
      return Outcome::finding;
    }
    return Outcome::rejected;
  } catch (const std::exception& e) {
    why = std::string("exception other than InputError: ") + e.what();
    return Outcome::finding;
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (s > max_seconds) {
    why = "accepted, but took " + std::to_string(s) + " s";
    return Outcome::finding;
  }
  return Outcome::accepted;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: fuzz_readers CORPUS_DIR [--runs N] [--seed S] [--max-seconds-per-input T] [--replay DIR]\n");
    return 2;
  }
  const fs::path corpus = argv[1];
  long runs = 2000;
  unsigned seed = 15;
  double max_seconds = 5;
  fs::path replay;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--runs") runs = std::atol(argv[i + 1]);
    else if (a == "--seed") seed = unsigned(std::atol(argv[i + 1]));
    else if (a == "--max-seconds-per-input") max_seconds = std::atof(argv[i + 1]);
    else if (a == "--replay") replay = argv[i + 1];
  }
  const fs::path work = fs::temp_directory_path() / ("lambert_fuzz_" + std::to_string(::getpid()));
  fs::create_directories(work);
  // The MTL the OBJ seeds name, and the scene the JSON seeds are applied to.
  put(work / "two.mtl", slurp(corpus / "obj" / "two.mtl"));
  put(work / "scene.obj", slurp(corpus / "obj" / "two.obj"));
  std::map<std::string, Counts> counts;
  int findings = 0;
  auto kind_of = [](const fs::path& p) {
    std::string e = p.extension().string();
    return e == ".obj" ? "obj" : e == ".ply" ? "ply" : e == ".off" ? "off" : e == ".json" ? "json" : e == ".mtl" ? "mtl" : "";
  };
  auto one = [&](const std::string& kind, const std::string& content, const std::string& label) {
    std::string target = kind == "mtl" ? "obj" : kind;
    const fs::path file = work / ("input." + (kind == "json" ? std::string("json") : target));
    if (kind == "mtl") {
      put(work / "two.mtl", content);
      put(file, slurp(corpus / "obj" / "two.obj"));
    } else {
      put(file, content);
    }
    std::string why;
    const Outcome o = exercise(kind == "mtl" ? "obj" : kind, file, work / "scene.obj", max_seconds, why);
    if (kind == "mtl") put(work / "two.mtl", slurp(corpus / "obj" / "two.mtl"));
    Counts& c = counts[kind];
    ++c.runs;
    if (o == Outcome::accepted) ++c.accepted;
    if (o == Outcome::rejected) ++c.rejected;
    if (o == Outcome::finding) {
      ++findings;
      const std::string name = "fuzz-finding-" + std::to_string(findings) + "." + (kind == "mtl" ? "mtl" : target);
      put(name, content);
      std::fprintf(stderr, "FINDING (%s, %s): %s; input saved as %s\n", kind.c_str(), label.c_str(), why.c_str(), name.c_str());
    }
  };
  if (!replay.empty()) {
    for (const auto& e : fs::directory_iterator(replay)) {
      const std::string kind = kind_of(e.path());
      if (!kind.empty()) one(kind, slurp(e.path()), e.path().filename().string());
    }
  } else {
    std::vector<std::pair<std::string, std::string>> seeds;  // kind, content
    for (const char* sub : {"obj", "ply", "off", "json"})
      for (const auto& e : fs::directory_iterator(corpus / sub)) {
        const std::string kind = kind_of(e.path());
        if (!kind.empty()) seeds.emplace_back(kind, slurp(e.path()));
      }
    std::sort(seeds.begin(), seeds.end());  // directory order is not deterministic
    Mutator m(seed);
    std::mt19937 pick(seed + 1);
    for (long r = 0; r < runs; ++r) {
      const auto& [kind, content] = seeds[pick() % seeds.size()];
      one(kind, m.mutate(content), "run " + std::to_string(r) + " seed " + std::to_string(seed));
    }
  }
  fs::remove_all(work);
  long total = 0;
  for (const auto& [kind, c] : counts) {
    std::printf("%-5s runs %6ld  rejected (InputError) %6ld  accepted %6ld\n", kind.c_str(), c.runs, c.rejected, c.accepted);
    total += c.runs;
  }
  std::printf("total %ld inputs, %d findings\n", total, findings);
  return findings ? 1 : 0;
}
