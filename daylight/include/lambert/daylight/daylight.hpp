#pragma once
// Daylight: the sky's direct irradiance on patches (an emission term for the solve), glazing, and irradiance at
// sensor points gathered from every patch (exact point-to-polygon kernel, ray visibility) plus the sky.
// Units: as the sky's (W m^-2 sr^-1 -> W m^-2; cd m^-2 -> lux). Colour: RGB per patch / sensor; the sky is grey.
// Method and its limits: docs/physics.md §9.
#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lambert/daylight/sky.hpp"
#include "lambert/formfactor/dense.hpp"
#include "lambert/formfactor/visibility.hpp"
#include "lambert/mesh/scene.hpp"

namespace lambert::daylight {

// Luminance weights of an RGB triple and the luminous efficacy that turns W into lm (Radiance's convention:
// Y = 0.265 R + 0.670 G + 0.065 B, 179 lm/W; see docs/physics.md §9 for why).
constexpr double kWeightR = 0.265, kWeightG = 0.670, kWeightB = 0.065;
constexpr double kEfficacy = 179.0;  // lm W^-1
inline double luminance_weighted(const RGB& c) { return kWeightR * c[0] + kWeightG * c[1] + kWeightB * c[2]; }

// Point-to-patches gathering with visibility. The light from the patches uses the exact point-to-polygon kernel
// times a visible fraction estimated with rays (formfactor's Visibility: Embree stays inside formfactor). The
// open directions (what the sky term needs) are exact: when no patch can hide another from x, the hemisphere
// minus the patches' moments; otherwise the patches are projected onto the faces of a hemicube around n and
// subtracted from them, nearest first through a tree (Clipper, integer coordinates of 2^-28 of a face: a relative
// error ~1e-8), and the moments of the uncovered region are integrated as polygons (docs/physics.md §9).
class Gatherer {
 public:
  // rays: visibility samples per (point, patch) pair that may be occluded (>= 1).
  // The geometry must outlive the Gatherer (it is referenced, not copied).
  Gatherer(const mesh::PatchGeometry& geometry, int rays);
  ~Gatherer();
  struct Result {
    RGB from_patches = RGB::Zero();  // pi sum_j V_j F(x -> P_j) L_j: light from the patches (needs radiance)
    Moments open;                    // the moments of the directions in which x sees no patch (sky and ground)
    bool clipped = false;            // open came from exact clipping (some patch could hide another)
  };
  // x, n (unit): the point and its normal; radiance: patches x 3 or empty (then from_patches = 0); ignore: a
  // patch the point lies on (its own plane's patches are ignored too), or -1.
  Result gather(const Vec3& x, const Vec3& n, const Vec3& up, const ColorField* radiance, int ignore) const;
  long long rays_cast() const;
  // The open directions' moments at x (exact clipping, as in gather()); likely_visible[j] != 0 marks patches x
  // probably sees (e.g. F_ij > 0): a hint that speeds the clipping up in rooms (the result moves by rounding on the
  // clipping's grid only, ~1e-9). Empty: no hint (the patches are then visited nearest first through a tree, only
  // where the hemicube is still open).
  Moments open(const Vec3& x, const Vec3& n, const Vec3& up, int ignore, const std::vector<char>& likely_visible) const;
  const mesh::PatchGeometry& geometry() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct PatchSkyStats {
  int patches_lit = 0;          // patches with E_sky > 1e-6 E_h (below: cracks of the clipping's integer grid)
  long long points = 0;         // points at which the open directions were clipped
  int negative_set_to_zero = 0; // patches whose E_sky came out < 0 (round-off of the clipping), set to 0
  double most_negative = 0;     // the most negative value before that (same unit as the sky's irradiance)
  int glazing_patches = 0;
  int enclosed = 0;             // patches whose front lies inside a closed surface: no sky, nothing clipped
  // Area (m^2) of the patches whose front sees no patch in more than half its (cosine-weighted) directions, facing
  // the sky (normal . up > 0.5: ground, roofs with nothing above) and facing the earth (< -0.5: with nothing below;
  // a ceiling sees its floor). Much more of the second is the mark of a model inside out (a mirrored export).
  double area_facing_up = 0, area_facing_down = 0;
  double seconds = 0;
};

// Direct sky (and ground) irradiance on each patch, at its centroid (at its largest triangle's centroid when the
// centroid lies off a non-convex patch): the sky and ground seen through the directions in which that point sees
// no patch (exact clipping, Gatherer::open); exactly 0, without clipping, for a patch whose front lies inside a
// closed surface (formfactor::enclosed_patches). likely_visible(i, flags), if given, sets flags[j] != 0 for the
// patches i probably sees (e.g. F_ij > 0 of an assembled operator): a hint that orders the clipping and changes
// the result only by the grid's rounding (~1e-8). Returns one value per patch (W m^-2, as the sky's units).
using VisibilityHint = std::function<void(int i, std::vector<char>& likely_visible)>;
std::vector<double> patch_sky_irradiance(const mesh::Scene& scene, const Sky& sky, const Gatherer& gather,
                                         PatchSkyStats* stats, const VisibilityHint& likely_visible = {},
                                         const std::function<void(double fraction_done)>& progress = {});

// Irradiance on the outside (back) of each glazing patch (transmittance > 0) from sky and ground, averaged over
// the patch, occluded by the scene's patches (two-sided); 0 for other patches.
std::vector<double> glazing_outside_irradiance(const mesh::Scene& scene, const Sky& sky, const Gatherer& gather);

// The emission the solve needs: Le_i + rho_i E_sky,i / pi + tau_i E_out,i / pi per channel.
ColorField daylight_emission(const mesh::Scene& scene, const std::vector<double>& sky_irradiance,
                             const std::vector<double>& outside_irradiance);

// --- sensors -----------------------------------------------------------------------------------------------
struct Sensor {
  Vec3 position = Vec3::Zero();
  Vec3 normal = Vec3::UnitY();  // unit
  int floor = -1;               // work-plane nodes: the floor patch under the node; -1 for sensors from a file
};

// CSV with columns x,y,z,nx,ny,nz (metres; the normal need not be unit, is normalised), one sensor per line; an
// optional header (the first line, with no numeric field; a UTF-8 byte-order mark is skipped); blank lines and
// lines starting with '#' skipped. Throws InputError naming file:line for a wrong column count, a non-number,
// NaN/Inf, or a zero normal; and for a file without sensors.
std::vector<Sensor> read_sensors_csv(const std::string& path);

// Work-plane grid (docs/physics.md §9): a square grid of `spacing` (m) at `height` (m) above the floors, normal
// up. Floors are patches facing up (normal within 1 degree of up) with no other up-facing surface 0.01 to 2.5 m
// lower within 2 m horizontally (so table tops, beds, cupboards and shelves are not floors, a rug on the floor
// is, and so is the floor of a storey above another; a floor step of more than 1 cm is not). Grid nodes lie on the
// lattice origin + spacing (i + 1/2, j + 1/2) over the floors' bounding box, its axes along the direction (modulo
// quarter turns) most floor-edge length follows (a turned building gets the upright one's nodes); a node is kept
// when its foot lies on a floor patch, nothing but up-facing surfaces (a table top) lies between the foot and the
// work plane (a ceiling lower than the work plane drops it), and nothing lies within `inset` (m) of it horizontally
// (16 rays at the work plane's height: walls, and furniture reaching it). Order: floor patches in scene order, then
// lattice rows.
struct WorkPlaneOptions {
  double height = 0.85, spacing = 0.5, inset = 0.5;
};
std::vector<Sensor> work_plane_grid(const mesh::PatchGeometry& geometry, const Vec3& up, const WorkPlaneOptions& options);

struct SensorResult {
  RGB irradiance = RGB::Zero();  // total, per channel
  RGB from_patches = RGB::Zero();  // interreflected part (and electric light)
  double sky = 0;                // the sky component (direct sky + ground), grey
};
// Irradiance at each sensor: from every patch (exact kernel, visibility by rays) with the solved radiance, plus
// the sky (sky may be null: no daylight).
// progress: called with the fraction done from any thread (the callee must be thread-safe).
std::vector<SensorResult> evaluate_sensors(const std::vector<Sensor>& sensors, const Gatherer& gather,
                                           const ColorField& radiance, const Sky* sky, const Vec3& up,
                                           const std::function<void(double fraction_done)>& progress = {});

}  // namespace lambert::daylight
