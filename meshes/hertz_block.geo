// The block (-1,1)^2 x (0,1) that a rigid sphere presses from below at the origin (3-D Hertz contact):
// Gamma_C = the bottom face z = 0, Gamma_D = the other five. The cells grow from 0.04 within 0.15 of the
// origin at 0.3 per unit distance, so that `refine: uniform` halves them all: the contact disk (radius ~0.1)
// is resolved on every level while the block stays small. The flat faces stay exact under refinement.
SetFactory("OpenCASCADE");
Box(1) = {-1, -1, 0, 2, 2, 1};
boundary[] = Boundary{ Volume{1}; };
bottom[] = Surface In BoundingBox{-1.1, -1.1, -0.1, 1.1, 1.1, 0.1};
others[] = boundary[];
others[] -= bottom[];
Physical Surface("contact") = {bottom[]};
Physical Surface("dirichlet") = {others[]};
Physical Volume("domain") = {1};
Field[1] = MathEval;
Field[1].F = "0.04 + 0.3 * Max(0, Sqrt(x^2 + y^2 + z^2) - 0.15)";
Background Field = 1;
