// A tiny unit square (linear triangles) for the reader fuzz test (tests/test_fuzz.cpp).
// Physical groups: "left" (x = 0), "right" (x = 1), "square" (the surface).
lc = 0.3;
Point(1) = {0, 0, 0, lc};
Point(2) = {1, 0, 0, lc};
Point(3) = {1, 1, 0, lc};
Point(4) = {0, 1, 0, lc};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Curve("left") = {4};
Physical Curve("right") = {2};
Physical Surface("square") = {1};
