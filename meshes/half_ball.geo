// Half-ball {|x| < 1, z < 0}: a ball pressed on the plane below it.
// Gamma_C = the lower hemisphere (curved), Gamma_D = the flat disk z = 0.
// Mesh nodes lie on the sphere; the facets make a polyhedron inscribed in it (see README, curved domains).
SetFactory("OpenCASCADE");
Sphere(1) = {0, 0, 0, 1, -Pi/2, 0, 2*Pi};   // latitudes -pi/2 .. 0: the lower half, closed by the disk
boundary[] = Boundary{ Volume{1}; };
flat[] = Surface In BoundingBox{-1.1, -1.1, -0.01, 1.1, 1.1, 0.01};
curved[] = boundary[];
curved[] -= flat[];
Physical Surface("contact") = {curved[]};
Physical Surface("dirichlet") = {flat[]};
Physical Volume("domain") = {1};
