#include "lambert/refine/json.hpp"

#include <nlohmann/json.hpp>

#include "lambert/formfactor/json.hpp"

namespace lambert::refine {

void to_json(nlohmann::json& j, const AdaptiveRound& r) {
  j = {{"patches", r.patches},
       {"pairs_total", r.pairs_total},
       {"pairs_reused", r.pairs_reused},
       {"error_estimate", r.error_estimate},
       {"marked", r.marked},
       {"split", r.split},
       {"solve_converged", r.solve_converged},
       {"solve_residual", r.solve_residual},
       {"seconds", {{"form_factors", r.assemble_seconds}, {"solve", r.solve_seconds}, {"indicators", r.indicator_seconds}}},
       {"form_factors", r.ff}};
}

void to_json(nlohmann::json& j, const AdaptiveResult& r) {
  j = {{"patches_per_round", r.patches_per_round},
       {"max_indicator", r.max_indicator},
       {"error_estimate", r.error_estimate},
       {"rounds", r.rounds},
       {"stop", r.stop},
       {"not_splittable", r.not_splittable},
       {"seconds", r.seconds}};
}

}  // namespace lambert::refine
