// The unit cube of tet4 elements of size 0.25 (1,125 cells), with the boundary groups x0, x1, z0
// and the volume group body; partitioned into 4 parts, one file each, for the test that a
// partitioned mesh gives the same bits on one rank and on three (tests/CMakeLists.txt).
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Mesh.MeshSizeMax = 0.25;
e = 1e-6;
Physical Volume("body") = {1};
Physical Surface("x0") = Surface In BoundingBox{-e, -e, -e, e, 1 + e, 1 + e};
Physical Surface("z0") = Surface In BoundingBox{-e, -e, -e, 1 + e, 1 + e, e};
Physical Surface("x1") = Surface In BoundingBox{1 - e, -e, -e, 1 + e, 1 + e, 1 + e};
