#include "lambert/mesh/json.hpp"

#include <nlohmann/json.hpp>

namespace lambert::mesh {

void to_json(nlohmann::json& j, const Report& r) {
  j = nlohmann::json::object();
  j["counts"] = r.counts;
  j["messages"] = r.warnings;
  j["worst_nonplanarity_m"] = r.worst_nonplanarity;
  j["worst_nonplanar_face"] = r.worst_nonplanar_face;
  auto& sec = j["seconds"] = nlohmann::json::object();
  for (const auto& [stage, t] : r.seconds) sec[stage] = sec.value(stage, 0.0) + t;
}

}  // namespace lambert::mesh
