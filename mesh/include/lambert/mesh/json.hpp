#pragma once
// JSON form of the mesh module's reports, for `--stats` (one schema, written beside the types).
#include <nlohmann/json_fwd.hpp>

#include "lambert/mesh/scene.hpp"

namespace lambert::mesh {

// {"counts": {kind: n}, "messages": [...], "worst_nonplanarity_m": m, "worst_nonplanar_face": k}
void to_json(nlohmann::json& j, const Report& r);

}  // namespace lambert::mesh
