#include "lambert/formfactor/json.hpp"

#include <nlohmann/json.hpp>

namespace lambert::formfactor {

void to_json(nlohmann::json& j, const RowsAboveOne& r) {
  j = {{"rows", r.rows},
       {"max_ratio", r.max_ratio},
       {"worst_patch", r.worst_patch},
       {"worst_row_sum", r.worst_row_sum},
       {"worst_allowed", r.worst_allowed}};
}

void to_json(nlohmann::json& j, const Stats& s) {
  j = nlohmann::json::object();
  j["rule"] = s.rule;
  j["tolerance"] = s.tolerance;
  j["visibility"] = s.visibility;
  j["rays_per_pair"] = s.rays_per_pair;
  j["patches"] = s.patches;
  j["pairs_total"] = s.pairs_total;
  j["pairs_orientation_culled"] = s.pairs_orientation_culled;
  j["pairs_shaft_culled"] = s.pairs_shaft_culled;
  j["pairs_ray_tested"] = s.pairs_ray_tested;
  j["visibility_method"] = s.visibility_method;
  j["pairs_exact_clear"] = s.pairs_exact_clear;
  j["pairs_exact_hidden"] = s.pairs_exact_hidden;
  j["pairs_plane_hidden"] = s.pairs_plane_hidden;
  j["enclosures"] = {{"surfaces", s.enclosures}, {"cells", s.cells}, {"patches_of_unknown_cell", s.cell_unknown},
                     {"pairs_refused", s.pairs_cell_hidden}};
  j["portals"] = {{"openings", s.portals}, {"rooms", s.rooms}, {"pairs_refused", s.pairs_portal_hidden}};
  j["plane_tests"] = s.plane_tests;
  j["pairs_exact_integrated"] = s.pairs_exact_integrated;
  j["pairs_exact_over_tolerance"] = s.pairs_exact_over_tolerance;
  j["exact_points"] = s.exact_points;
  j["occluders_merged"] = s.occluders_merged;
  j["occluder_regions"] = s.occluder_regions;
  j["convex_solids"] = s.convex_solids;
  j["convex_solid_faces"] = s.convex_solid_faces;
  j["pairs_by_method"] = s.pairs_by_method;
  j["pairs_reused"] = s.pairs_reused;
  j["pairs_over_tolerance"] = s.pairs_over_tolerance;
  j["rays_cast"] = s.rays_cast;
  j["scene_can_occlude"] = s.scene_can_occlude;
  j["occluders"] = s.occluders;
  j["row_sum"] = {{"min", s.row_sum_min}, {"max", s.row_sum_max}, {"mean", s.row_sum_mean}};
  j["row_error_bound_max"] = s.row_error_bound_max;
  j["rows_above_one"] = s.rows_above_one;
  j["row_visibility_sigma_max"] = s.row_visibility_sigma_max;
  j["reciprocity_check_pairs"] = s.reciprocity_check_pairs;
  j["reciprocity_residual"] = s.reciprocity_residual;
  j["reciprocity_bound_ratio"] = s.reciprocity_bound_ratio;
  j["reciprocity_worst_method"] = s.reciprocity_worst_method;
  j["reciprocity_pairs_by_method"] = s.reciprocity_pairs_by_method;
  j["entries_roundoff"] = s.entries_roundoff;
  j["entries_outside_unit"] = s.entries_outside_unit;
  j["pairs_no_visible_sample"] = s.pairs_no_visible_sample;
  j["seconds"] = s.seconds;
  j["bytes"] = s.bytes;
}

}  // namespace lambert::formfactor
