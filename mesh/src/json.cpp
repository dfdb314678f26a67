#include "lambert/mesh/json.hpp"

#include <nlohmann/json.hpp>

namespace lambert::mesh {

void to_json(nlohmann::json& j, const Report& r) {
  j = nlohmann::json::object();
  j["counts"] = r.counts;
  j["messages"] = r.warnings;
  j["worst_nonplanarity_m"] = r.worst_nonplanarity;
  j["worst_nonplanar_face"] = r.worst_nonplanar_face;
}

}  // namespace lambert::mesh
