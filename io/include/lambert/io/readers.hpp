#pragma once
// Scene file readers and writers: OBJ (+MTL), PLY (ascii / binary), OFF (+COFF), materials JSON.
// Readers check syntax only and return faces in file order; mesh::build_scene does the geometry
// and value-range checks. Every error throws lambert::InputError starting "FILE:LINE: " (or naming
// the element index for binary PLY) and saying what was found and what was expected.
// Coordinates are taken as metres; colours and reflectances are per channel in [0, 1].
#include <string>

#include "lambert/mesh/soup.hpp"

namespace lambert::io {

// Wavefront OBJ: v, f (v, v/vt, v//vn, v/vt/vn, negative indices), o/g (-> groups), mtllib, usemtl.
// MTL: newmtl, Kd (reflectance), Ke (radiance W m^-2 sr^-1); one value means grey; "two_sided" or
// "two_sided 1" (a lambert extension; "two_sided 0" = one-sided, the default) marks the material
// two-sided (Material::two_sided). Faces before
// any usemtl get material 0 and are counted in faces_without_material. An MTL material named
// "default" replaces material 0.
mesh::PolygonSoup read_obj(const std::string& path);

// PLY ascii / binary_little_endian / binary_big_endian. Vertex x, y, z (any scalar type), face
// vertex_indices or vertex_index (any list type). Optional face red/green/blue: 8-bit integers are
// divided by 255, 16-bit by 65535, 32-bit integers by 255, floats taken as is. Each distinct colour
// becomes one material named "color_R_G_B" (R = 0..255 when the value is k/255 exactly, else the
// shortest exact decimal, e.g. "color_0.3_0.3_0.3"); faces without colour get material 0.
mesh::PolygonSoup read_ply(const std::string& path);

// OFF / COFF / NOFF / CNOFF (vertex extras ignored). Faces "n i1 .. in [r g b [a]]": colour values
// written all as integers are 0..255, otherwise floats 0..1; materials as for PLY.
mesh::PolygonSoup read_off(const std::string& path);

// STL, binary or ASCII, told apart by content (not by extension): binary when the file size is exactly
// 84 + 50 x (the header's facet count), else ASCII when it starts with "solid", else a binary file whose
// count lies (an error naming the first incomplete facet). Facet k is input face k (a triangle with its
// own three vertices: mesh::prepare welds them). The facet normal is ignored: the vertex order (right-hand
// rule) gives the front side, as for every format. ASCII "solid NAME" names a group. Every face gets
// material 0 ("default"; --materials names or face ranges override it). Errors name the facet (and the
// line for ASCII).
mesh::PolygonSoup read_stl(const std::string& path);

// Dispatches on the extension (.obj, .ply, .off, .stl, case-insensitive); any other extension by
// content (PLY and OFF magic words, STL as read_stl tells it).
mesh::PolygonSoup read_soup(const std::string& path);

// Applies a --materials JSON file:
//   {"materials": {"NAME": {"reflectance": R, "emission": E, "two_sided": B}, ...},
//    "faces": [{"range": [first, last], "material": "NAME"} |
//              {"range": [...], "reflectance": R, "emission": E, "two_sided": B}]}
// B: true or false (default false: one-sided).
// R, E: a number (grey) or an array of 1 or 3 numbers. "materials" entries override only the given
// fields of the material with that name, or create it (grey 0.5, no emission). "faces" ranges are
// inclusive 0-based input face indices; inline values create a material "faces_FIRST-LAST".
// Later entries win. Unused JSON materials are reported in soup.warnings. Value ranges are not
// checked here (build_scene does, naming Material::defined_at = the JSON file).
void apply_materials_json(mesh::PolygonSoup& soup, const std::string& json_path);

// Writers: shortest decimal that reads back to the same double (exact round trip), written to a
// temporary name and renamed. Failures throw InputError naming the path.
// OBJ: positions, faces in order, groups (g), materials in OBJ_STEM.mtl next to it (Kd, Ke).
void write_obj(const mesh::PolygonSoup& soup, const std::string& obj_path);
// PLY/OFF keep only each material's reflectance, as a face colour (names and emission are lost):
// PLY writes a colour for every face once any face has a material other than 0; OFF only for those.
// Colours are 8-bit when every value is k/255 exactly, else double (PLY) / decimals (OFF).
void write_ply(const mesh::PolygonSoup& soup, const std::string& path, bool binary);
void write_off(const mesh::PolygonSoup& soup, const std::string& path);
// STL keeps only geometry: faces as triangles (n-gons ear-clipped), binary (float32) or ASCII.
void write_stl(const mesh::PolygonSoup& soup, const std::string& path, bool binary);

}  // namespace lambert::io
