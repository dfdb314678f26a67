#pragma once
// `solve` with daylight and photometry (--sky, sensors, --units): option checks, the sky's emission term, the
// sensors, and their outputs, summary lines and --stats block. The numerics live in daylight/.
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "commands.hpp"
#include "lambert/daylight/daylight.hpp"
#include "lambert/io/vtk.hpp"

namespace lambert::app {

// Checks the daylight options and declares their files (sensor CSV as input; --sensors-out and its .vtu as
// outputs) before any work; InputError on a bad value or combination.
void declare_daylight_files(const CommonOptions& o);

class DaylightRun {
 public:
  explicit DaylightRun(const CommonOptions& o);  // parses the options (InputError)
  bool sky_active() const { return has_sky_; }
  const daylight::PatchSkyStats& patch_stats() const { return patch_stats_; }  // after emission()
  bool sensors_requested() const { return !o_.sensors.empty() || o_.work_plane > 0; }
  bool active() const { return has_sky_ || sensors_requested() || photometric_; }

  // Emission for the solve: Le + rho E_sky / pi + tau E_out / pi (scene.emission_field() without a sky).
  ColorField emission(const mesh::Scene& scene, const formfactor::DenseMatrixOperator* F, bool quiet);
  // Sensors after the solve (reads or generates them).
  void sensors(const mesh::Scene& scene, const ColorField& radiance, bool quiet);

  // The .vtu's extra arrays; `irradiance` gains the direct sky.
  std::vector<io::ExtraArray> cell_arrays(const mesh::Scene& scene, const ColorField& radiance,
                                          ColorField& irradiance) const;
  void write_outputs() const;  // --sensors-out CSV and .vtu into the output transaction
  std::string summary() const;
  nlohmann::json stats() const;

 private:
  CommonOptions o_;
  bool has_sky_ = false, photometric_ = false;
  daylight::Sky sky_;
  Vec3 up_ = Vec3::UnitY();
  std::vector<double> patch_sky_, outside_;
  daylight::PatchSkyStats patch_stats_;
  std::unique_ptr<daylight::Gatherer> gatherer_;
  std::vector<daylight::Sensor> sensors_;
  std::vector<daylight::SensorResult> results_;
  double sensor_seconds_ = 0, sky_seconds_ = 0;
  long long sensor_rays_ = 0;
  std::string sensor_source_;
  std::vector<std::string> sensor_room_;  // work plane: the room of each node (its floor's group up to '/')
  double scale() const;             // output unit per internal W: 179 (photometric) or 1
  double value(const RGB& e) const;  // Y-weighted, in output units
};

}  // namespace lambert::app
