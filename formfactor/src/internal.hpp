#pragma once
// Internals of the form-factor module (not installed). Units: metres; F dimensionless.
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "atan_reduced.hpp"
#include "batch.hpp"
#include "lambert/formfactor/assemble.hpp"
#include "lambert/mesh/geometry.hpp"

namespace lambert::formfactor::detail {

constexpr double kPi = 3.14159265358979323846;

// Gauss-Kronrod 7/15 nodes and weights on [-1, 1] (nodes >= 0; the rule is symmetric).
inline constexpr double kXgk[8] = {0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
                                   0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
                                   0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
                                   0.207784955007898467600689403773245, 0.000000000000000000000000000000000};
inline constexpr double kWgk[8] = {0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
                                   0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
                                   0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
                                   0.204432940075298892414161999234649, 0.209482141084727828012999174891714};
inline constexpr double kWg[4] = {0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                                  0.381830050505118944950369775488975, 0.417959183673469387755102040816327};

// atan2(z, w) for z >= 0, in [0, pi]: the rational approximation of the SIMD kernels (atan_reduced.hpp), ~1 ulp,
// about 3x faster than std::atan2 (which was a tenth of the hierarchy's build on the generated building).
inline double atan2_pos(double z, double w) {
  const double aw = w < 0 ? -w : w;
  const double mx = z > aw ? z : aw, mn = z > aw ? aw : z;
  const bool big = mn > kAtanSplit * mx;
  const double num = big ? mn - mx : mn;
  double den = big ? mn + mx : mx;
  if (!(den > 0)) den = 1.0;
  const double at = atan_reduced(num / den);
  const double phi = big ? (kPi / 4) + (at + kPio4Tail) : at;
  const double th = z > aw ? (kPi / 2) - phi : phi;
  return w < 0 ? kPi - th : th;
}

// Corners of `poly` with n.y - offset >= -eps (Sutherland-Hodgman). Vertices within eps of the plane are kept
// as they are. For a non-convex polygon the result may contain doubled "bridge" edges along the plane; both
// the contour formula and the double line integral are sums over edges in which those cancel exactly.
void clip_front(std::span<const Vec3> poly, const Vec3& n, double offset, double eps, std::vector<Vec3>& out);

// (1/2pi)|sum_k theta_k n.c_k/|c_k||: the point-to-polygon form factor with no culling or clipping; the caller
// guarantees that the polygon lies in x's closed front half-space and x is in front of it.
// Form factors do not change under translation, but computing them far from the origin loses digits: at 1e6 m a
// coordinate carries ~1e-10 m of round-off, which near pairs' rules amplify (examples/room.obj moved by
// (1e6, 0, -2e6) m failed its reciprocity check at 9x the bound). Nor under rotation, but the shafts and cluster
// boxes are axis-aligned: the generated 10k building turned about (3, -1, 2) by 1.1 rad proved 2.7x fewer pairs clear
// (hierarchical form factors 3.9 -> 10.6 s; 5.2 s on the turned copy). A copy of g moved so that its bounding-box
// centre is at the origin (if that centre lies farther from the origin than the box's diagonal) and turned so that
// the directions most of its area faces (mesh::alignment(g)) lie along the axes (if they are more than 1 degree off);
// else null.
std::unique_ptr<mesh::PatchGeometry> moved_to_origin(const mesh::PatchGeometry& g);

// Signed Lambert contour sum sum_k theta_k n.c_k/|c_k| (no absolute value, no 1/2pi): additive over oriented
// contours, so holes with reversed orientation subtract (exact visibility's unions).
double signed_contour_sum(const Vec3& x, const Vec3& n, std::span<const Vec3> poly);
double contour_sum(const Vec3& x, const Vec3& n, std::span<const Vec3> poly);

// A_i F_ij (m^2) by the double line integral (1/2pi) sum_ab (u_a.v_b) int int ln r ds dt, adaptive
// Gauss-Kronrod on each edge of i with the inner edge integral in closed form. Precondition: Pi lies in the
// closed front half-space of Pj's plane and vice versa (clip first). abs_tol bounds the error of A_i F_ij.
struct ContourResult {
  double AF = 0, error = 0;
  long long evaluations = 0;
};
ContourResult contour_pair(std::span<const Vec3> Pi, std::span<const Vec3> Pj, double abs_tol);

// Quadrature rules (points in reference coordinates, weights summing to 1).
struct Rule2D {
  std::vector<std::array<double, 2>> xi;  // reference coordinates
  std::vector<double> w;
};
// m x m Gauss-Legendre on [0,1]^2 (degree 2m-1).
const Rule2D& gauss_square(int m);
// Collapsed (Duffy) m x m Gauss rule on the triangle (0,0),(1,0),(0,1): positive weights, exact for polynomials
// of degree 2m-2 (Gauss-Legendre in t times the Jacobian 1 - t; tiers.hpp's exponent for such sources is 2m-1).
const Rule2D& gauss_triangle(int m);
// 1D Gauss-Legendre on [0,1].
void gauss_legendre01(int m, std::vector<double>& x, std::vector<double>& w);

// Per-patch data used by the pair kernels.
struct PatchData {
  int n = 0;
  std::vector<Vec3> c, nrm;          // centroid, unit normal
  std::vector<double> area, radius;  // area, circumradius about the centroid
  // The tiers' source radius (r = rerr / d): the circumradius, or sqrt(6 lambda) with lambda the largest principal
  // second moment per area if larger. A square's is its circumradius; a strip L x W takes L / sqrt 2 (the square
  // whose side is its length) instead of L / 2: the Gauss rules' error in the long direction is that square's, and
  // with the circumradius a 60:1 strip's 6 x 6 estimate fell 6x short (ReciprocityHoldsForSlenderSources).
  std::vector<double> rerr;
  std::vector<double> offset;        // n . c
  std::vector<double> eps;           // plane classification tolerance (relative to scene size)
  std::vector<std::array<double, 6>> M;  // second-moment tensor / area about c: xx yy zz xy xz yz
  std::vector<std::array<double, 10>> M3;  // third moments / area about c, batch.hpp's kTriples (0: parallelograms)
  std::vector<std::uint8_t> kind;    // 0 = triangle, 1 = parallelogram, 2 = convex quad, 3 = general polygon
  // Outer rules: for m = 2, 3, 4 points per side, patch p: points [rule_off[m][p], rule_off[m][p+1]) in
  // rule_pts[m] (larger m are mapped per pair from reference rules).
  std::array<std::vector<int>, 5> rule_off;
  std::array<std::vector<std::array<double, 4>>, 5> rule_pts;  // x, y, z, weight (weights sum to 1 per patch)
  const mesh::PatchGeometry* g = nullptr;
  // The kernel's own copy of the geometry, each polygon projected onto its plane (through its centroid, along its
  // normal), when some polygon is not planar beyond round-off (a model rounded to single precision: quads 1e-8 m out
  // of plane); g then points to it, else to the geometry given. The tiers' Gauss points on a polygon's triangles and
  // its contour integrate one and the same planar polygon: on the non-planar one they differed by 3e-8 of F on a
  // 2.5 cm strip, 5x the error estimates, and the solve was refused. Visibility keeps the geometry as given (shared
  // corners, watertight).
  std::shared_ptr<const mesh::PatchGeometry> planar;
  double scene_eps = 0;
};
PatchData prepare(const mesh::PatchGeometry& g, int max_tier = 4);

// Outer-rule points of tier m on a polygon given by its triangles (m = 1: centroid), appended as x,y,z,w with
// weights normalised to sum 1. Quads that are convex use the m x m Gauss rule on their bilinear map.
void outer_rule(std::span<const Vec3> poly, std::span<const std::array<int, 3>> tris, int m,
                std::vector<std::array<double, 4>>& out);

// A-priori error model (tiers.hpp): estimate of |F_ij error| for tier t (0 = far field, 1 = centroid + Hessian
// correction, 2..6 = m x m Gauss, m = kTierM[t]) given S = A_j / (pi d^2), r = R_i / d, q = R_j / d (R the
// circumradii), d the distance from c_i to the bounding sphere of P_j.
double tier_error(int t, double S, double r, double q, bool source_symmetric, bool target_symmetric);

// Centroid value plus second-order (Hessian) correction; see pair.cpp.
double hessian_correction(const Vec3& ci, const Vec3& ni, const std::array<double, 6>& Mi, const Vec3& cj,
                          const Vec3& nj, double Aj);

// Point-to-point kernel at the centroids plus second-order corrections on both sides (tier 0).
double far_field(const Vec3& ci, const Vec3& ni, const std::array<double, 6>& Mi, const Vec3& cj, const Vec3& nj,
                 const std::array<double, 6>& Mj, double Aj);

// Unoccluded F_src,tgt for one pair by the full scalar path (classification, clipping, tier or contour).
struct PairEval {
  double F = 0, error = 0;
  int method = 0;  // index into kMethodNames
  long long evaluations = 0;
};
enum Method {
  kCulled = 0, kFarField, kCentroidHessian, kGauss4, kGauss9, kGauss16, kGauss36, kGauss64, kContour, kMethodCount
};
extern const char* const kMethodNames[kMethodCount];
int tier_method(int t);
PairEval pair_scalar(const PatchData& P, int src, int tgt, double tol);
// The source normals and target corners the SIMD point kernel reads (batch.hpp's SoA, only nx/ny/nz and qx/qy/qz
// set), for pair_scalar's outer Gauss rules: the same rule points, evaluated 8 (AVX-512), 4 or 2 at a time.
struct PointSoA {
  std::vector<double> cols;  // 15 columns of n + kBatchPad
  SoA soa{};
  explicit PointSoA(const PatchData& P);
};
// pair_scalar, with the Gauss rules' points on triangles and convex quads evaluated by the SIMD kernel.
PairEval pair_scalar(const PatchData& P, const PointSoA& soa, int src, int tgt, double tol);

// A_t F_ts (m^2) integrated from t's side, independently of the tiers: mutual clipping, then the adaptive
// double contour integral with t's edges outer, to an absolute error tol * A_s on A_t F_ts. For the
// reciprocity check (A_s F_st should equal it).
struct ReverseIntegral {
  double AF = 0, error = 0;
};
// entry_tol: the tolerance the entry was computed to; where pair_scalar took the bound of two clipped polygons apart
// instead of the integral (within half of it), so does this, and the two agree.
ReverseIntegral reverse_integral(const PatchData& P, int s, int t, double tol, double entry_tol);

// Signed distances of polygon corners to a plane: returns (min, max).
std::array<double, 2> plane_range(std::span<const Vec3> poly, const Vec3& n, double offset);

// Stats::rows_above_one from per-row sums, admitted errors and visibility sigmas (equal sizes); rows with
// skip[i] != 0 (skip empty or of the same size) are left out.
RowsAboveOne find_rows_above_one(std::span<const double> row_sums, std::span<const double> error,
                                 std::span<const double> sigma, std::span<const std::uint8_t> skip = {});

}  // namespace lambert::formfactor::detail
