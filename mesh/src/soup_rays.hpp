#pragma once
// Ray casting against the faces of a soup, in double precision (a BVH and a watertight triangle test, internal to mesh/):
// what mesh::prepare uses to see which side of a surface the scene sees, and whether a fragment is
// hidden. Embree stays in formfactor/.
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "lambert/mesh/soup.hpp"

namespace lambert::mesh::detail {

class SoupRays {
 public:
  // Faces with include[k] != 0 (usable faces) become triangles (ear clipping on their Newell plane).
  SoupRays(const PolygonSoup& s, const std::vector<char>& include);
  ~SoupRays();
  SoupRays(const SoupRays&) = delete;
  SoupRays& operator=(const SoupRays&) = delete;

  struct Hit {
    int face = -1;    // soup face hit first; -1: the ray escapes
    double t = 0;     // distance along the unit direction (m)
    bool front = false;  // the ray arrives at the face's front side (direction . normal < 0)
  };
  // First hit of the ray o + t d (|d| = 1, 0 <= t <= t_max) on a face for which skip(face) is false. A finite
  // t_max ends the ray there: a query skipping most faces then does not trace to the far end of the scene.
  Hit first(const Vec3& o, const Vec3& d, const std::function<bool(int)>& skip,
            double t_max = std::numeric_limits<double>::infinity()) const;

  // Unit Newell normal of face k (right-hand rule), zero if not included.
  const Vec3& normal(int k) const { return normal_[k]; }
  // A random point inside face k (uniform by area over its triangles).
  Vec3 sample(int k, std::mt19937_64& rng) const;
  // The same from three numbers in [0, 1): u0 picks the triangle (by area), u1 and u2 the point in it.
  Vec3 sample(int k, double u0, double u1, double u2) const;
  bool has(int k) const { return !tris_of_[k].empty(); }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<Vec3> normal_;
  std::vector<std::vector<std::array<Vec3, 3>>> tris_of_;
  std::vector<std::vector<double>> cum_area_;
};

// A cosine-distributed unit direction in the hemisphere around the unit normal n.
Vec3 cosine_direction(const Vec3& n, std::mt19937_64& rng);
// The same from two numbers in [0, 1) (u0: squared sine of the angle to n, u1: azimuth / 2 pi).
Vec3 cosine_direction(const Vec3& n, double u0, double u1);

}  // namespace lambert::mesh::detail
