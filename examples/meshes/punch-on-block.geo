// A square punch [0.3, 0.7] x [0.3, 0.7] x [1, 1.4] on the block [0, 1]^3, meshed apart (no
// shared nodes: OpenCASCADE boxes without fragments) with hex8 of different sizes: the block
// n x n x n, the punch m x m x 4 (default 10 and 9: the meshes do not match at the contact
// face). Physical groups: "block", "punch" (volumes), "block_bottom" (z = 0), "block_top"
// (z = 1), "punch_bottom" (z = 1), "punch_top" (z = 1.4).
// Regenerate: gmsh -3 -format msh41 punch-on-block.geo -o punch-on-block.msh
SetFactory("OpenCASCADE");
If (!Exists(n)) n = 10; EndIf
If (!Exists(m)) m = 9; EndIf
Box(1) = {0, 0, 0, 1, 1, 1};
Box(2) = {0.3, 0.3, 1, 0.4, 0.4, 0.4};
Macro Divide
  cs[] = Unique(Abs(Boundary{Surface{Abs(Boundary{Volume{vol};})};}));
  For i In {0:#cs[] - 1}
    bb[] = BoundingBox Curve{cs[i]};
    If (bb[5] - bb[2] > 1e-6)
      Transfinite Curve{cs[i]} = nz + 1;
    Else
      Transfinite Curve{cs[i]} = nxy + 1;
    EndIf
  EndFor
  Transfinite Surface{Abs(Boundary{Volume{vol};})};
  Recombine Surface{Abs(Boundary{Volume{vol};})};
  Transfinite Volume{vol};
Return
vol = 1; nxy = n; nz = n; Call Divide;
vol = 2; nxy = m; nz = 4; Call Divide;
Mesh.Recombine3DAll = 1;
// OpenCASCADE's box faces: x = 0, x = 1, y = 0, y = 1, z = 0, z = 1.
Physical Surface("block_bottom") = {5};
Physical Surface("block_top") = {6};
Physical Surface("punch_bottom") = {11};
Physical Surface("punch_top") = {12};
Physical Volume("block") = {1};
Physical Volume("punch") = {2};
