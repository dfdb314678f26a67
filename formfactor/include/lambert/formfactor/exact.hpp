#pragma once
// Closed-form view factors for verification (Howell's catalogue and the corner-sum forms behind it).
// Lengths in metres (any consistent unit); results dimensionless, from the first surface to the second.
namespace lambert::formfactor::exact {

// Two axis-aligned rectangles in the parallel planes z = 0 ([x1,x2] x [y1,y2]) and z = c > 0
// ([u1,u2] x [v1,v2]), facing each other. By superposition of the corner function parallel_corner.
double parallel_rectangles(double x1, double x2, double y1, double y2, double u1, double u2, double v1, double v2,
                           double c);
// Rectangle [x1,x2] x [z1,z2] in the plane y = 0 (z >= 0) to rectangle [u1,u2] x [y1,y2] in the plane z = 0
// (y >= 0); both face the quadrant y, z > 0. Rectangles may share the edge line (z1 = 0, y1 = 0).
double perpendicular_rectangles(double x1, double x2, double z1, double z2, double u1, double u2, double y1,
                                double y2);

// Corner functions: A_1 F_12 = signed sum over the 16 corner combinations (see exact.cpp).
double parallel_corner(double u, double v, double c);
double perpendicular_corner(double u, double s2);  // s2 = y^2 + z^2

// Catalogue C-11 (directly opposed a x b rectangles at distance c) and C-14 (perpendicular rectangles with
// a common edge of length l, widths w (first) and h (second)).
double opposed_rectangles(double a, double b, double c);
double perpendicular_common_edge(double l, double w, double h);
// Coaxial parallel disks of radii r1 (source) and r2 at distance h.
double coaxial_disks(double r1, double r2, double h);

}  // namespace lambert::formfactor::exact
