// The block of bench/distributed_input.py: [0,4] x [0,1] x [0,1] of tet4 elements of size h
// (1.8 M tetrahedra for h = 0.0215; Delaunay, whose mesh is the same on every run: HXT, the
// parallel algorithm, is faster but not repeatable), groups x0 (clamped), x1 (traction), body.
SetFactory("OpenCASCADE");
If (!Exists(h)) h = 0.0215; EndIf
Box(1) = {0, 0, 0, 4, 1, 1};
Mesh.MeshSizeMin = h;
Mesh.MeshSizeMax = h;
Mesh.Algorithm3D = 1;
e = 1e-6;
Physical Volume("body") = {1};
Physical Surface("x0") = Surface In BoundingBox{-e, -e, -e, e, 1 + e, 1 + e};
Physical Surface("x1") = Surface In BoundingBox{4 - e, -e, -e, 4 + e, 1 + e, 1 + e};
