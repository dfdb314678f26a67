#include "lambert/mesh/soup.hpp"

namespace lambert::mesh {

PolygonSoup make_empty_soup(std::string file) {
  PolygonSoup s;
  s.file = std::move(file);
  Material def;
  def.name = "default";
  def.defined_at = SourceLoc{"(built-in default)", 0};
  s.materials.push_back(def);
  return s;
}

}  // namespace lambert::mesh
