#pragma once
// Verification cases with exact answers (docs/physics.md §8): build the geometry, assemble form factors,
// solve, compare per patch. Used by `lambert verify sphere|furnace`, `lambert study` and the tests.
//
// Pass thresholds are fixed numbers stated from the error bounds the methods achieve (docs/benchmarks.md),
// never scaled by rho/(1 - rho): a case that amplifies its form-factor error beyond them fails. A case also
// fails when its error exceeds the a-posteriori bound predicted from its row sums and solve residual (the
// bound is a prediction made without the exact answer, so this checks the bound itself).
#include <map>
#include <string>

#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/geometry.hpp"
#include "lambert/solver/solve.hpp"

namespace lambert::verify {

using solver::Method;

// Icosphere (20 * 4^K flat triangles, corners on the sphere of radius R, normals inward): a closed
// convex polyhedron. Emission and reflectance are evaluated at each patch centroid c = (x, y, z):
//   uniform: Le = E0, rho = rho0. Exact discrete answer E0 / (1 - rho0), since every row of F sums
//            to 1; pass tolerance 1e-6 (form-factor and solver error only) at every rho.
//   cap:     Le = E0 where z > R/2, else 0; rho = rho0.
//   linear:  Le = E0 (1 + z/R) / 2; rho = rho0 (0.75 + 0.25 x/R).
// cap and linear are compared with the continuum answer of a true sphere, whose kernel is the constant
// 1/(4 pi R^2): L_i = Le_i + rho_i Ebar / (1 - rhobar), Ebar and rhobar the area means over the
// polyhedron. The polyhedron only converges to it, as O(h) in the edge length h = 1.0515 R / 2^K: a flat
// face's normal is radial at its circumcentre, not its centroid, and the cosines of the kernel are first
// order in that O(h) tilt; pass tolerance 0.2 h/R, several times the measured error
// (docs/benchmarks_solver.md).
struct SphereCase {
  int subdivisions = 3;       // K in [0, 6]: 1280 patches by default
  double radius = 1;          // m
  double rho = 0.9;           // rho0 in [0, 1)
  std::string emission = "uniform";  // "uniform" | "cap" | "linear"
  double E0 = 1;              // W m^-2 sr^-1
  formfactor::Options ff;     // the library's defaults: `verify` checks what users get
  solver::Options solve = tight_solve();
  double tolerance = 0;       // pass threshold on the max relative error; 0 = the case's default above
  // The solve stops at a relative residual of 1e-10 (not the CLI's 1e-8), so that its error is negligible
  // next to the form-factor error the case measures.
  static solver::Options tight_solve() {
    solver::Options o;
    o.tolerance = 1e-10;
    return o;
  }
};

// White furnace: closed unit room [0,1]^3 (divisions^2 quads per face, inward) with the floating block
// [0.35, 0.65]^3 (block_divisions^2 quads per face, outward) that occludes. Uniform Le = E0, rho: exact
// answer E0 / (1 - rho) everywhere. Row-sum errors delta (from ray-estimated visibility) are amplified:
// the error is at most rho max|delta| / (1 - rho max(1 + delta)), printed as "bound". Pass tolerance 5e-3,
// fixed, from what ray visibility with 256 rays per pair achieves on this room up to rho = 0.99
// (docs/benchmarks.md); at rho = 0.999 ray visibility is not accurate enough and the case fails, as it
// should.
struct FurnaceCase {
  int divisions = 6;          // >= 1: 216 room quads
  int block_divisions = 3;    // >= 1: 54 block quads
  double rho = 0.9;
  double E0 = 1;              // W m^-2 sr^-1
  formfactor::Options ff = more_rays();  // the library's defaults, but 256 rays per partially occluded pair
  solver::Options solve = SphereCase::tight_solve();
  double tolerance = 0;       // pass threshold on the max relative error; 0 = the default above
  // Scale: the room is [0, size]^3 (block scaled with it). speck > 0 adds a cube of that edge (outward, one
  // quad per face) floating at 0.2 size: a closed scene spanning speck..size metres, same exact answer.
  double size = 1;
  double speck = 0;
  static formfactor::Options more_rays() {
    formfactor::Options o;
    o.rays_per_pair = 256;
    return o;
  }
};

struct VerifyReport {
  std::string name;                        // e.g. "sphere K=3 uniform rho=0.9"
  int patches = 0;
  std::map<std::string, double> seconds;  // "mesh", "form_factors", "solve", "total"
  Method method = Method::Auto;            // the method used
  int iterations = 0;                      // max over channels
  int matvecs = 0;                         // max over channels
  double residual = 0;                     // max relative residual over channels
  bool converged = false;
  double row_sum_min = 0, row_sum_max = 0;
  double error_bound = 0;   // a-posteriori bound from row sums and residual (uniform sphere, furnace); 0 otherwise
  double max_rel_error = 0, mean_rel_error = 0;  // |L_i - exact_i| / exact_i over patches
  double rms_rel_error = 0;                      // area-weighted root mean square of the same
  int worst_patch = -1;
  double tolerance = 0;     // the pass threshold applied to max_rel_error
  bool within_bound = true; // max_rel_error <= error_bound (when a bound exists)
  bool passed = false;      // converged, max_rel_error <= tolerance, and within_bound
  formfactor::Stats ff;     // form-factor statistics (rays, pairs, visibility time)
  std::string table;        // ready-to-print text
};

// The parts of the cases, for studies that assemble once and solve many times (lambert study).
mesh::PatchGeometry sphere_geometry(const SphereCase& c);
void sphere_fields(const SphereCase& c, const mesh::PatchGeometry& g, ColorField& rho, ColorField& Le);
// Exact answer per patch (channel 0); `basis` (optional) says which (discrete or continuum).
Eigen::VectorXd sphere_exact(const SphereCase& c, const mesh::PatchGeometry& g, std::string* basis = nullptr);
mesh::PatchGeometry furnace_geometry(const FurnaceCase& c);
// max / mean / area-weighted RMS of |L_i - exact_i| / exact_i, worst patch; into r.
void relative_error(const Eigen::VectorXd& L, const Eigen::VectorXd& exact, const std::vector<double>& area,
                    VerifyReport& r);

// Throw InputError for out-of-range parameters (names the field and the allowed range).
VerifyReport verify_sphere(const SphereCase& c);
VerifyReport verify_furnace(const FurnaceCase& c);

}  // namespace lambert::verify
