// Half-disk {x^2 + y^2 < 1, y < 0}: a disk pressed on the plane below it.
// Gamma_C = the lower half circle (curved), Gamma_D = the diameter y = 0.
// Mesh nodes lie on the circle; the cells make a polygon inscribed in it (see README, curved domains).
Point(1) = {0, 0, 0};   // centre of the arcs only; not a mesh node
Point(2) = {1, 0, 0};
Point(3) = {0, -1, 0};
Point(4) = {-1, 0, 0};
Circle(1) = {2, 1, 3};  // built-in arcs must span less than pi: two quarter circles
Circle(2) = {3, 1, 4};
Line(3) = {4, 2};
Curve Loop(1) = {1, 2, 3};
Plane Surface(1) = {1};
Physical Curve("contact") = {1, 2};
Physical Curve("dirichlet") = {3};
Physical Surface("domain") = {1};
