#pragma once
// The polygon soup that file readers produce: positions, faces in file order, materials.
// Nothing is validated beyond syntax here; mesh::build_scene does the geometric checks.
#include <optional>
#include <string>
#include <vector>

#include "lambert/mesh/types.hpp"

namespace lambert::mesh {

struct Material {
  std::string name;
  RGB reflectance = RGB::Constant(0.5);  // diffuse albedo rho per channel, must lie in [0, 1)
  RGB emission = RGB::Zero();            // emitted radiance Le, W m^-2 sr^-1, must be >= 0
  bool two_sided = false;                // each face becomes two patches, front and back (mesh::prepare)
  SourceLoc defined_at;                  // where the values came from (MTL line, JSON file, ...)
  // Diffuse visible transmittance tau per channel (glazing; MTL `transmittance`, a lambert extension):
  // in [0, 1] with reflectance + transmittance <= 1. Only a daylight solve (--sky) uses it: the patch then
  // passes tau of the irradiance reaching its back (outside) into the room, diffusely (daylight/).
  // (Last, so that aggregate initialisers of the fields above stay valid.)
  RGB transmittance = RGB::Zero();
};

struct SoupFace {
  std::vector<int> vertices;  // 0-based indices into PolygonSoup::positions, >= 3, in winding order
  int material = 0;           // index into PolygonSoup::materials
  int group = -1;             // index into PolygonSoup::groups (OBJ o/g name), -1 = none
  int line = 0;               // 1-based line of the face in the source file (0 for binary formats)
  int origin = -1;            // input face this face was made from (mesh::prepare splits and refines
                              // faces); -1 = its own index. Scene::face_id and messages use it.
  int side = 0;               // 0: the face as given; 1: the back of a two-sided face (reversed copy)
};

struct PolygonSoup {
  std::string file;                  // source path, for messages
  std::vector<Vec3> positions;       // metres
  std::vector<int> position_lines;   // source line of each position (0 if unknown)
  std::vector<SoupFace> faces;       // file order: faces[k] is input face k (face_id = k), unless
                                     // faces[k].origin >= 0 names the input face it came from
  std::vector<Material> materials;   // materials[0] is the default material "default"
  std::vector<std::string> groups;   // OBJ object/group names
  long faces_without_material = 0;   // faces that got the default material (reported)
  std::vector<std::string> warnings; // reader-level warnings (ignored statements, unused materials, ...)
  int input_faces = -1;              // faces in the input file when faces were split or dropped; -1 = faces.size()
};

// A soup with only the default material (grey, rho = 0.5, no emission).
PolygonSoup make_empty_soup(std::string file);

}  // namespace lambert::mesh
