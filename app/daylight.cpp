#include "daylight.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <cmath>
#include <nlohmann/json.hpp>

#include "outputs.hpp"
#include "progress.hpp"

namespace lambert::app {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDefaultHorizontalLux = 10000;  // default sky: E_h = 10,000 lx (the CIE overcast design value)

// The sensors' .vtu: OUT.vtu beside --sensors-out OUT.csv (OUT.csv.vtu for another extension), or OUT.sensors.vtu
// when OUT.vtu is the -o output itself (`-o city.vtu --sensors-out city.csv`, the natural pair of names).
std::string sensors_vtu_path(const CommonOptions& o) {
  const std::string& csv = o.sensors_out;
  const std::string ext = ".csv";
  const bool dot_csv = csv.size() > ext.size() && csv.compare(csv.size() - ext.size(), ext.size(), ext) == 0;
  const std::string stem = dot_csv ? csv.substr(0, csv.size() - ext.size()) : csv;
  namespace fs = std::filesystem;
  std::error_code e1, e2;
  const fs::path beside = fs::weakly_canonical(stem + ".vtu", e1), output = fs::weakly_canonical(o.output, e2);
  if (!o.output.empty() && (stem + ".vtu" == o.output || (!e1 && !e2 && beside == output))) return stem + ".sensors.vtu";
  return stem + ".vtu";
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

void declare_daylight_files(const CommonOptions& o) {
  DaylightRun check(o);  // parses and checks every option
  if (!o.sensors.empty()) outputs().add_input(o.sensors);
  if (!o.sensors_out.empty()) {
    outputs().add_output(o.sensors_out, "--sensors-out");
    outputs().add_output(sensors_vtu_path(o), "--sensors-out points (the .vtu written beside '" + o.sensors_out + "')");
  }
}

DaylightRun::DaylightRun(const CommonOptions& o) : o_(o) {
  if (o.units != "radiometric" && o.units != "photometric")
    throw InputError("--units " + o.units + ": expected radiometric or photometric");
  photometric_ = o.units == "photometric";
  up_ = daylight::parse_axis(o.up);
  if (!(o.ground_reflectance >= 0 && o.ground_reflectance <= 1))
    throw InputError(fmt::format("--ground-reflectance {}: expected a number in [0, 1]", o.ground_reflectance));
  if (!o.sky.empty()) {
    has_sky_ = true;
    sky_ = daylight::parse_sky(o.sky, -1);
    if (sky_.radiance < 0) {  // default: E_h = 10,000 lx
      const double per_unit = sky_.kind == daylight::Sky::Kind::Uniform ? kPi : 7.0 / 9.0 * kPi;
      sky_.radiance = kDefaultHorizontalLux / daylight::kEfficacy / per_unit;
    } else if (photometric_) {
      sky_.radiance /= daylight::kEfficacy;  // cd m^-2 -> W m^-2 sr^-1 (grey: Y = value)
    }
    sky_.ground_reflectance = o.ground_reflectance;
    sky_.up = up_;
  }
  if (!o.sensors.empty() && o.work_plane > 0)
    throw InputError("--sensors and --work-plane: give one source of sensors, not both");
  if (o.work_plane > 0 && !(o.grid > 0)) throw InputError("--work-plane needs --grid SPACING (metres)");
  if (o.grid > 0 && !(o.work_plane > 0)) throw InputError("--grid needs --work-plane HEIGHT (metres)");
  if (!o.sensors_out.empty() && !sensors_requested())
    throw InputError("--sensors-out needs sensors: --sensors IN.csv or --work-plane HEIGHT --grid SPACING");
  if (o.adaptive_budget > 0 && active())
    throw InputError("--adaptive-budget cannot be combined with --sky, sensors or --units photometric yet");
}

double DaylightRun::scale() const { return photometric_ ? daylight::kEfficacy : 1.0; }
double DaylightRun::value(const RGB& e) const { return scale() * daylight::luminance_weighted(e); }

ColorField DaylightRun::emission(const mesh::Scene& scene, const formfactor::DenseMatrixOperator* F, bool quiet) {
  if (!has_sky_) return scene.emission_field();
  const auto t0 = std::chrono::steady_clock::now();
  if (!gatherer_) gatherer_ = std::make_unique<daylight::Gatherer>(scene.geometry, o_.sensor_rays);
  {
    Progress progress("sky", !quiet);
    // The dense rows tell which patches each patch sees (F_ij > 0), a hint for the sky gatherer's occluder
    // search; the hierarchical operator has no rows and gives no hint (same result, more occluder tests).
    daylight::VisibilityHint seen;
    if (F) {
      seen = [&M = F->matrix()](int i, std::vector<char>& flags) {
        for (Eigen::Index j = 0; j < M.cols(); ++j) flags[size_t(j)] = M(i, j) > 0;  // F_ij > 0: i sees j
      };
    }
    patch_sky_ = daylight::patch_sky_irradiance(scene, sky_, *gatherer_, &patch_stats_, seen,
                                                [&](double f) { progress.update(f); });
  }
  outside_.assign(size_t(scene.patches()), 0.0);
  if (patch_stats_.glazing_patches > 0) {
    outside_ = daylight::glazing_outside_irradiance(scene, sky_, *gatherer_);
  }
  sky_seconds_ = seconds_since(t0);
  return daylight::daylight_emission(scene, patch_sky_, outside_);
}

void DaylightRun::sensors(const mesh::Scene& scene, const ColorField& radiance, bool quiet) {
  if (!sensors_requested()) return;
  const auto t0 = std::chrono::steady_clock::now();
  if (!o_.sensors.empty()) {
    sensors_ = daylight::read_sensors_csv(o_.sensors);
    sensor_source_ = o_.sensors;
  } else {
    daylight::WorkPlaneOptions w;
    w.height = o_.work_plane;
    w.spacing = o_.grid;
    w.inset = o_.grid_inset;
    sensors_ = daylight::work_plane_grid(scene.geometry, up_, w);
    // Rooms: the floor's group name up to its first '/' ("living/floor_2" -> "living"), the OBJ convention of
    // ROOM/OBJECT names; floors without a group form one room "(no group)".
    for (const daylight::Sensor& s : sensors_) {
      const int g = s.floor >= 0 && s.floor < int(scene.group.size()) ? scene.group[size_t(s.floor)] : -1;
      const std::string name = g >= 0 ? scene.groups[size_t(g)] : "(no group)";
      sensor_room_.push_back(name.substr(0, name.find('/')));
    }
    sensor_source_ = fmt::format("work plane {} m, grid {} m, inset {} m", w.height, w.spacing, w.inset);
  }
  if (!gatherer_) gatherer_ = std::make_unique<daylight::Gatherer>(scene.geometry, o_.sensor_rays);
  const long long before = gatherer_->rays_cast();
  {
    Progress progress("sensors", !quiet);
    results_ = daylight::evaluate_sensors(sensors_, *gatherer_, radiance, has_sky_ ? &sky_ : nullptr, up_,
                                          [&](double f) { progress.update(f); });
  }
  sensor_rays_ = gatherer_->rays_cast() - before;
  sensor_seconds_ = seconds_since(t0);
}

std::vector<io::ExtraArray> DaylightRun::cell_arrays(const mesh::Scene& scene, const ColorField& radiance,
                                                     ColorField& irradiance) const {
  std::vector<io::ExtraArray> out;
  const int n = scene.patches();
  if (has_sky_) {
    io::ExtraArray a{"sky_irradiance", 1, std::vector<double>(size_t(n)), false};
    for (int p = 0; p < n; ++p) {
      a.values[size_t(p)] = patch_sky_[size_t(p)];
      irradiance.row(p).array() += patch_sky_[size_t(p)];
    }
    out.push_back(std::move(a));
    if (patch_stats_.glazing_patches > 0) {
      io::ExtraArray g{"outside_irradiance", 1, outside_, false};
      out.push_back(std::move(g));
    }
  }
  if (photometric_) {
    io::ExtraArray lum{"luminance", 1, std::vector<double>(size_t(n)), true};
    io::ExtraArray ill{"illuminance", 1, std::vector<double>(size_t(n)), false};
    for (int p = 0; p < n; ++p) {
      lum.values[size_t(p)] = value(radiance.row(p).transpose().array());
      ill.values[size_t(p)] = value(irradiance.row(p).transpose().array());
    }
    out.push_back(std::move(lum));
    out.push_back(std::move(ill));
  }
  return out;
}

void DaylightRun::write_outputs() const {
  if (o_.sensors_out.empty()) return;
  const double Eh = has_sky_ ? sky_.horizontal_irradiance() : 0.0;
  write_output(o_.sensors_out, [&](std::ostream& os) {
    std::string buf = "x,y,z,illuminance,daylight_factor\n";
    for (size_t k = 0; k < sensors_.size(); ++k) {
      const Vec3& x = sensors_[k].position;
      const RGB& e = results_[k].irradiance;
      buf += fmt::format("{:.10g},{:.10g},{:.10g},{:.10g},", x.x(), x.y(), x.z(), value(e));
      if (has_sky_) buf += fmt::format("{:.10g}", 100 * daylight::luminance_weighted(e) / Eh);
      buf += '\n';
    }
    os << buf;
  });
  write_output(sensors_vtu_path(o_), [&](std::ostream& os) {
    std::vector<Vec3> pts;
    io::ExtraArray ill{"illuminance", 1, {}, false}, df{"daylight_factor", 1, {}, false};
    io::ExtraArray irr{"irradiance", 3, {}, false}, sky{"sky_component", 1, {}, false}, nrm{"normal", 3, {}, false};
    for (size_t k = 0; k < sensors_.size(); ++k) {
      pts.push_back(sensors_[k].position);
      const RGB& e = results_[k].irradiance;
      ill.values.push_back(value(e));
      df.values.push_back(has_sky_ ? 100 * daylight::luminance_weighted(e) / Eh : std::nan(""));
      for (int c = 0; c < 3; ++c) irr.values.push_back(e[c]);
      sky.values.push_back(results_[k].sky * scale());
      for (int c = 0; c < 3; ++c) nrm.values.push_back(sensors_[k].normal[c]);
    }
    io::write_points_vtu(os, pts, {ill, df, irr, sky, nrm});
  });
}

namespace {
struct Figures {
  double mean = 0, min = 0, max = 0;
};
Figures figures(const std::vector<double>& v) {
  Figures f;
  if (v.empty()) return f;
  f.min = *std::min_element(v.begin(), v.end());
  f.max = *std::max_element(v.begin(), v.end());
  double s = 0;
  for (double x : v) s += x;
  f.mean = s / double(v.size());
  return f;
}
struct Room {
  std::string name;
  std::vector<double> E, df;
};

}  // namespace

// Work-plane figures per room (first-appearance order); empty unless the sensors come from a work plane.
static std::vector<Room> rooms(const std::vector<std::string>& room_of, const std::vector<double>& E,
                               const std::vector<double>& df) {
  std::vector<Room> out;
  for (size_t k = 0; k < room_of.size() && k < E.size(); ++k) {
    auto it = std::find_if(out.begin(), out.end(), [&](const Room& r) { return r.name == room_of[k]; });
    if (it == out.end()) it = out.insert(out.end(), Room{room_of[k], {}, {}});
    it->E.push_back(E[k]);
    if (k < df.size()) it->df.push_back(df[k]);
  }
  return out;
}

std::string DaylightRun::summary() const {
  std::string s;
  const char* lux = photometric_ ? "lx" : "W m^-2";
  if (has_sky_) {
    s += fmt::format("  daylight     {} sky, {} {:.5g} {}, horizontal {:.5g} {}, ground reflectance {:g}, up {}; "
                     "sky on {} patches ({} inside closed surfaces get none), {} glazing patches ({:.3g} s)\n",
                     sky_.name(), sky_.kind == daylight::Sky::Kind::Uniform ? "L" : "Lz", sky_.radiance * scale(),
                     photometric_ ? "cd m^-2" : "W m^-2 sr^-1", sky_.horizontal_irradiance() * scale(), lux,
                     sky_.ground_reflectance, o_.up, patch_stats_.patches_lit, patch_stats_.enclosed,
                     patch_stats_.glazing_patches, sky_seconds_);
    if (patch_stats_.negative_set_to_zero > 0)
      s += fmt::format("  note         {} patches had a negative sky irradiance from round-off (most negative {:.3g} {}), "
                       "set to 0\n",
                       patch_stats_.negative_set_to_zero, patch_stats_.most_negative * scale(), lux);
  }
  if (!results_.empty()) {
    std::vector<double> E, df;
    for (const auto& r : results_) {
      E.push_back(value(r.irradiance));
      if (has_sky_) df.push_back(100 * daylight::luminance_weighted(r.irradiance) / sky_.horizontal_irradiance());
    }
    const Figures f = figures(E);
    s += fmt::format("  sensors      {} ({}): illuminance mean {:.4g} {}, min {:.4g}, max {:.4g}, uniformity "
                     "(min/mean) {:.3g}; {} rays, {:.3g} s\n",
                     results_.size(), sensor_source_, f.mean, lux, f.min, f.max, f.mean > 0 ? f.min / f.mean : 0.0,
                     sensor_rays_, sensor_seconds_);
    if (has_sky_) {
      const Figures d = figures(df);
      s += fmt::format("  daylight factor  mean {:.3g} %, min {:.3g} %, max {:.3g} %, uniformity {:.3g}\n", d.mean,
                       d.min, d.max, d.mean > 0 ? d.min / d.mean : 0.0);
    }
    const auto per_room = rooms(sensor_room_, E, df);
    if (per_room.size() > 1)
      for (const Room& r : per_room) {
        const Figures e = figures(r.E);
        s += fmt::format("    {:<14} {:>5} sensors: mean {:.4g} {}, min {:.4g}, uniformity {:.3g}", r.name, r.E.size(),
                         e.mean, lux, e.min, e.mean > 0 ? e.min / e.mean : 0.0);
        if (!r.df.empty()) {
          const Figures d = figures(r.df);
          s += fmt::format("; daylight factor mean {:.3g} %, min {:.3g} %", d.mean, d.min);
        }
        s += '\n';
      }
    if (!o_.sensors_out.empty())
      s += fmt::format("  sensors out  {} and {}\n", o_.sensors_out, sensors_vtu_path(o_));
  }
  return s;
}

nlohmann::json DaylightRun::stats() const {
  using nlohmann::json;
  json j;
  j["units"] = o_.units;
  j["efficacy_lm_per_W"] = daylight::kEfficacy;
  j["luminance_weights"] = {daylight::kWeightR, daylight::kWeightG, daylight::kWeightB};
  j["up"] = o_.up;
  if (has_sky_) {
    j["sky"] = {{"kind", sky_.name()},
                {"radiance", sky_.radiance * scale()},
                {"horizontal_illuminance", sky_.horizontal_irradiance() * scale()},
                {"ground_reflectance", sky_.ground_reflectance},
                {"patches_lit", patch_stats_.patches_lit},
                {"glazing_patches", patch_stats_.glazing_patches},
                {"patches_enclosed", patch_stats_.enclosed},
                {"points_clipped", patch_stats_.points},
                {"negative_set_to_zero", patch_stats_.negative_set_to_zero},
                {"most_negative", patch_stats_.most_negative * scale()},
                {"open_area_facing_up", patch_stats_.area_facing_up},
                {"open_area_facing_down", patch_stats_.area_facing_down},
                {"seconds", sky_seconds_}};
  }
  if (!results_.empty()) {
    std::vector<double> E, df;
    for (const auto& r : results_) {
      E.push_back(value(r.irradiance));
      if (has_sky_) df.push_back(100 * daylight::luminance_weighted(r.irradiance) / sky_.horizontal_irradiance());
    }
    const Figures f = figures(E);
    json s = {{"count", results_.size()},   {"source", sensor_source_}, {"illuminance_mean", f.mean},
              {"illuminance_min", f.min},   {"illuminance_max", f.max},
              {"uniformity", f.mean > 0 ? f.min / f.mean : 0.0},
              {"rays", sensor_rays_},       {"rays_per_patch", o_.sensor_rays},  {"seconds", sensor_seconds_}};
    if (has_sky_) {
      const Figures d = figures(df);
      s["daylight_factor_mean"] = d.mean;
      s["daylight_factor_min"] = d.min;
      s["daylight_factor_max"] = d.max;
    }
    if (!o_.sensors_out.empty()) s["output"] = {o_.sensors_out, sensors_vtu_path(o_)};
    json by_room = json::array();
    for (const Room& r : rooms(sensor_room_, E, df)) {
      const Figures e = figures(r.E);
      json jr = {{"room", r.name}, {"count", r.E.size()}, {"illuminance_mean", e.mean}, {"illuminance_min", e.min},
                 {"uniformity", e.mean > 0 ? e.min / e.mean : 0.0}};
      if (!r.df.empty()) {
        const Figures d = figures(r.df);
        jr["daylight_factor_mean"] = d.mean;
        jr["daylight_factor_min"] = d.min;
      }
      by_room.push_back(jr);
    }
    if (!by_room.empty()) s["rooms"] = by_room;
    j["sensors"] = s;
  }
  return j;
}

}  // namespace lambert::app
