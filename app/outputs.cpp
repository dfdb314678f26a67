#include "outputs.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <cmath>
#include <set>

#include "lambert/mesh/types.hpp"

namespace lambert::app {

io::OutputSet& outputs() {
  static io::OutputSet set;
  return set;
}

void declare_files(const CommonOptions& o) {
  io::OutputSet& out = outputs();
  if (!o.scene.empty()) out.add_input(o.scene);
  if (!o.materials.empty()) out.add_input(o.materials);
  if (!o.output.empty()) out.add_output(o.output, "-o");
  if (!o.stats.empty()) out.add_output(o.stats, "--stats");
}

void declare_soup_inputs(const mesh::PolygonSoup& soup) {
  std::set<std::string> files;
  for (const auto& m : soup.materials)
    if (!m.defined_at.file.empty() && m.defined_at.file != soup.file) files.insert(m.defined_at.file);
  for (const auto& f : files) outputs().add_input(f);
}

void write_output(const std::string& path, const std::function<void(std::ostream&)>& fill) { outputs().write(path, fill); }

void commit_outputs() { outputs().commit(); }

namespace {
double physical_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return double(8ull << 30);
  return double(pages) * double(page);
}
}  // namespace

long long max_patches_in_memory() {
  // formfactor::assemble refuses N^2 * 8 bytes above 80% of physical memory; the same bound.
  return static_cast<long long>(std::floor(std::sqrt(0.8 * physical_bytes() / 8.0)));
}

long long max_patches_in_memory(const CommonOptions& o) {
  if (o.op == "dense" || o.adaptive_budget > 0) return max_patches_in_memory();
  // The largest n whose estimate fits (the estimate grows monotonically with n): bisection.
  const std::size_t limit = formfactor::system_memory_limit().bytes;
  long long lo = 1, hi = 1LL << 31;
  while (hi - lo > 1) {
    const long long mid = lo + (hi - lo) / 2;
    (formfactor::estimate_hierarchy_bytes(std::size_t(mid), o.hierarchy.tolerance) <= limit ? lo : hi) = mid;
  }
  return std::max(max_patches_in_memory(), lo);
}

void check_adaptive_budget(const CommonOptions& o) {
  if (o.adaptive_budget <= 0) return;
  const long long limit = max_patches_in_memory();
  if (o.adaptive_budget > limit)
    throw InputError(fmt::format(
        "--adaptive-budget {}: the final form-factor matrix would need {:.3g} GB ({}^2 doubles), more than the "
        "{:.3g} GB allowed (80% of physical memory); the largest budget that fits is {}: choose a smaller "
        "--adaptive-budget",
        o.adaptive_budget, 8.0 * double(o.adaptive_budget) * double(o.adaptive_budget) / 1e9, o.adaptive_budget,
        0.8 * physical_bytes() / 1e9, limit));
}

}  // namespace lambert::app
