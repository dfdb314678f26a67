#include "lambert/solver/json.hpp"

#include <algorithm>
#include <nlohmann/json.hpp>

namespace lambert::solver {
namespace {
nlohmann::json rgb(const RGB& c) { return nlohmann::json::array({c[0], c[1], c[2]}); }
}  // namespace

void to_json(nlohmann::json& j, const ChannelReport& c) {
  j = {{"iterations", c.iterations}, {"matvecs", c.matvecs}, {"residual", c.residual}, {"residual_max", c.residual_max},
       {"stop", c.stop}};
}

void to_json(nlohmann::json& j, const Solution& s) {
  int iterations = 0;
  double residual = 0;
  for (const auto& c : s.channels) {
    iterations = std::max(iterations, c.iterations);
    residual = std::max(residual, c.residual);
  }
  j = nlohmann::json::object();
  j["method"] = to_string(s.method);
  j["iterations"] = iterations;
  j["residual"] = residual;
  j["converged"] = s.converged;
  j["channels"] = s.channels;
  j["solver_warnings"] = s.warnings;
  j["energy"] = {{"emitted_W", rgb(s.emitted)},
                 {"absorbed_W", rgb(s.absorbed)},
                 {"escaped_W", rgb(s.escaped)},
                 {"balance_residual", s.energy_residual}};
}

}  // namespace lambert::solver
