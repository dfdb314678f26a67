#pragma once
// JSON form of the assembly's statistics, for `--stats` (the "form_factors" block; one schema, written
// beside the type it describes). Keys are the Stats field names (see assemble.hpp for meanings and units).
#include <nlohmann/json_fwd.hpp>

#include "lambert/formfactor/assemble.hpp"

namespace lambert::formfactor {

void to_json(nlohmann::json& j, const Stats& s);
void to_json(nlohmann::json& j, const RowsAboveOne& r);  // rows, max_ratio, worst_patch, worst_row_sum, worst_allowed

}  // namespace lambert::formfactor
