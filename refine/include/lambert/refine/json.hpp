#pragma once
// JSON form of an adaptive refinement, for `--stats` (the "adaptive" block; one schema beside the types):
// patches_per_round, max_indicator, error_estimate, stop, not_splittable, and per round its counts,
// timings, solve convergence and the round's form-factor statistics.
#include <nlohmann/json_fwd.hpp>

#include "lambert/refine/adaptive.hpp"

namespace lambert::refine {

void to_json(nlohmann::json& j, const AdaptiveRound& r);
void to_json(nlohmann::json& j, const AdaptiveResult& r);

}  // namespace lambert::refine
