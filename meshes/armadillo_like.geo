// The armadillo-like solid of the scatter scene (`--mesh armadillo-like`), as a gmsh script.
// The same construction and mesh options as dolfinx_invertible/meshes/armadillo_like.py at
// its defaults (resolution 4). Mesh it with `gmsh armadillo_like.geo -3`. The scenes use this
// mesh translated to the bounding box's low corner and scaled to a largest extent of 1
// (`size`); meshes/armadillo_like.msh is that mesh, written by meshes/generate.py.
SetFactory("OpenCASCADE");

resolution = 4;

Sphere(1) = {0, 0, 0, 0.25};  // torso
Dilate {{0, 0, 0}, {1.5, 1.0, 0.8}} { Volume{1}; }
Sphere(2) = {0.42, 0, 0.1, 0.12};  // head
Cylinder(3) = {-0.2, -0.15, -0.05, 0, 0, -0.3, 0.05};  // legs
Cylinder(4) = {-0.2, 0.15, -0.05, 0, 0, -0.3, 0.05};
Cylinder(5) = {0.2, -0.15, -0.05, 0, 0, -0.3, 0.05};
Cylinder(6) = {0.2, 0.15, -0.05, 0, 0, -0.3, 0.05};
Cylinder(7) = {-0.35, 0, 0, -0.3, 0, 0.1, 0.035};  // tail
Cone(8) = {0.45, -0.06, 0.18, 0, 0, 0.1, 0.035, 0.02};  // ears
Cone(9) = {0.45, 0.06, 0.18, 0, 0, 0.1, 0.035, 0.02};
body() = BooleanUnion{ Volume{1}; Delete; }{ Volume{2:9}; Delete; };
Cylinder(20) = {0, -0.4, 0, 0, 0.8, 0, 0.07};  // the through hole
solid() = BooleanDifference{ Volume{body()}; Delete; }{ Volume{20}; Delete; };

box() = BoundingBox Volume{solid()};
extent = Max(box(3) - box(0), Max(box(4) - box(1), box(5) - box(2)));
length = extent / (6 * resolution);
Mesh.CharacteristicLengthMin = 0.7 * length;
Mesh.CharacteristicLengthMax = length;
Mesh.Algorithm3D = 1;
Mesh.Optimize = 1;

Physical Volume("body", 1) = {solid()};
