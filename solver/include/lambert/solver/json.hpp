#pragma once
// JSON form of a solve, for `--stats` (one schema, written beside the types). A Solution serialises to
// the keys that --stats has at its top level: "method", "iterations" (largest over channels), "residual"
// (largest relative residual), "converged", "channels" (per channel: iterations, matvecs, residual, stop),
// "solver_warnings" and "energy" (emitted_W, absorbed_W, escaped_W per channel, balance_residual).
#include <nlohmann/json_fwd.hpp>

#include "lambert/solver/solve.hpp"

namespace lambert::solver {

void to_json(nlohmann::json& j, const ChannelReport& c);
void to_json(nlohmann::json& j, const Solution& s);

}  // namespace lambert::solver
