// A structured hex8 block [0, 1] x [0, 1] x [-1, 0] graded toward the origin, a point of its top
// face (z = 0): n cells per side, the first of size hmin, each next r times larger (r from
// hmin (r^n - 1) / (r - 1) = 1), the same along x, y and z. Cells far along one axis and near
// the other two are stretched (up to 0.2 x 0.005 x 0.005 with the defaults): a mesh biased as
// engineers bias structured meshes toward a contact. hmin = 1 / n: the uniform mesh.
// Groups: top (z = 0), bottom, x0, y0 (the symmetry planes of a quarter model), block.
// bench/graded_hertz.py: gmsh -3 -setnumber hmin H -format msh41 graded_block_hex.geo -o F.msh
If (!Exists(n)) n = 32; EndIf
If (!Exists(hmin)) hmin = 0.005; EndIf
r = 1.2;
For k In {1:200}
  r = (1 + (r - 1) / hmin)^(1 / n);
EndFor
num[] = {};
hts[] = {};
s = 0;
For i In {0:n - 1}
  s += hmin * r^i;
  num[] += 1;
  hts[] += s;
EndFor
For i In {0:n - 1}
  hts[i] = hts[i] / s;
EndFor
Point(1) = {0, 0, 0};
l[] = Extrude {1, 0, 0} { Point{1}; Layers{num[], hts[]}; };
f[] = Extrude {0, 1, 0} { Line{l[1]}; Layers{num[], hts[]}; Recombine; };
v[] = Extrude {0, 0, -1} { Surface{f[1]}; Layers{num[], hts[]}; Recombine; };
e = 1e-6;
Physical Surface("top") = Surface In BoundingBox{-e, -e, -e, 1 + e, 1 + e, e};
Physical Surface("bottom") = Surface In BoundingBox{-e, -e, -1 - e, 1 + e, 1 + e, -1 + e};
Physical Surface("x0") = Surface In BoundingBox{-e, -e, -1 - e, e, 1 + e, e};
Physical Surface("y0") = Surface In BoundingBox{-e, -e, -1 - e, 1 + e, e, e};
Physical Volume("block") = {v[1]};
