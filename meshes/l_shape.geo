// L-shape (-1,1)^2 minus [0,1] x [-1,0], re-entrant corner (interior angle 3 pi / 2) at the origin.
// Gamma_C = (0,1) x {0}, an edge ending at the re-entrant corner, where it meets Gamma_D
// (the edge {0} x (-1,0)): the Gamma_C/Gamma_D interface singularity of the paper's Remark 3.4.
Point(1) = {0, 0, 0};
Point(2) = {1, 0, 0};
Point(3) = {1, 1, 0};
Point(4) = {-1, 1, 0};
Point(5) = {-1, -1, 0};
Point(6) = {0, -1, 0};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 6};
Line(6) = {6, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6};
Plane Surface(1) = {1};
Physical Curve("contact") = {1};
Physical Curve("dirichlet") = {2, 3, 4, 5, 6};
Physical Surface("domain") = {1};
