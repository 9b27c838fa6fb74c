// The paper's two membranes (0,1)^2 and (1,2) x (0,1) as two bodies meshed apart with quad4 of
// different sizes: n1 x n1 and n2 x n2 elements (default 48 and 64; multiples of 4 keep the
// load's jumps at y = 0.25 and 0.75 on element edges), so that the meshes do not match on the
// contact line x = 1. Physical groups: "membrane1", "membrane2" (surfaces), "left" (x = 0),
// "right1" (x = 1 of membrane 1), "left2" (x = 1 of membrane 2).
// Regenerate: gmsh -2 -format msh41 membranes-two-bodies.geo -o membranes-two-bodies.msh
SetFactory("OpenCASCADE");
If (!Exists(n1)) n1 = 48; EndIf
If (!Exists(n2)) n2 = 64; EndIf
Rectangle(1) = {0, 0, 0, 1, 1};
Rectangle(2) = {1, 0, 0, 1, 1};
Transfinite Curve{1, 2, 3, 4} = n1 + 1;
Transfinite Curve{5, 6, 7, 8} = n2 + 1;
Transfinite Surface{1, 2};
Recombine Surface{1, 2};
// OpenCASCADE numbers a rectangle's sides bottom, right, top, left.
Physical Curve("left") = {4};
Physical Curve("right1") = {2};
Physical Curve("left2") = {8};
Physical Surface("membrane1") = {1};
Physical Surface("membrane2") = {2};
