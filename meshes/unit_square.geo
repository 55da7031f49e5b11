// Unit square (0,1)^2, meshed unstructured. Gamma_C = the bottom edge y = 0; Gamma_D = the other three.
// The target cell size is set by signorini (Mesh.MeshSizeMax); points carry no size of their own.
Point(1) = {0, 0, 0};
Point(2) = {1, 0, 0};
Point(3) = {1, 1, 0};
Point(4) = {0, 1, 0};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Curve("contact") = {1};
Physical Curve("dirichlet") = {2, 3, 4};
Physical Surface("domain") = {1};
