// Headless software rendering of a triangle mesh into an RgbImage (z-buffer, Lambert shading), so that
// every tool can write a picture of a mesh without OpenGL or OpenCV.
//
// Typical use:
//   RenderOptions options;                       // 800×600, orthographic, looking along −z
//   options.view_direction = {1, -1, -1};        // any direction; the view fits the bounding box
//   RgbImage before = RenderMesh(noisy, options);
//   RgbImage after = RenderMesh(smoothed, options);
//   WritePng(SideBySide({before, after}), "before_after.png");   // pipeline/png.h
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "core/image.h"
#include "core/mesh.h"
#include "core/mesh_io.h"  // CornerNormals

namespace rangebayes {

enum class Projection { kOrthographic, kPerspective };

// Which normals the Lambert term uses.
//   kFlat:   one normal per face (facets visible: what a noisy scan or a decimated mesh looks like).
//   kSmooth: per-corner normals when RenderOptions::corner_normals is given, else Mesh::N when it has one
//            row per vertex, else area-weighted vertex normals computed here; interpolated across the face.
enum class Shading { kFlat, kSmooth };

// Row-major #F×3 colour table (one RGB per face, components in [0, 1]).
using FaceColors = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct RenderOptions {
  int width_px = 800;   // image width, [1, 16384]
  int height_px = 600;  // image height, [1, 16384]
  // Direction the camera looks along, in model coordinates (need not be unit; must not be zero). The camera
  // is placed outside the bounding box so that the whole mesh fits the image with `margin_fraction` around it.
  Eigen::Vector3d view_direction{0.0, 0.0, -1.0};
  // Approximate up direction of the image in model coordinates; made orthogonal to view_direction. When it
  // is (nearly) parallel to view_direction another axis is used.
  Eigen::Vector3d up{0.0, 1.0, 0.0};
  Projection projection = Projection::kOrthographic;
  double field_of_view_deg = 30.0;  // vertical field of view for kPerspective, (0, 170)
  double margin_fraction = 0.05;    // empty border around the fitted mesh, share of the image size, [0, 0.45]
  // The box the view is fitted to: its centre, and for orthographic views the projections of its corners.
  // Empty (the default): the bounding box of the mesh's finite vertices. Renderings of several meshes with
  // one fit_box share one framing; vertices outside it may fall outside the image (see CentralBox).
  Eigen::AlignedBox3d fit_box;
  Shading shading = Shading::kFlat;
  // Optional per-face colours (#F×3 in [0, 1]); empty: every face gets base_color.
  FaceColors face_colors;
  Eigen::Vector3f base_color{0.78f, 0.78f, 0.80f};  // RGB in [0, 1]
  // Optional per-corner normals: row 3·f + k is the normal of corner k of face f (#F·3 × 3, need not be unit).
  // Used by Shading::kSmooth (e.g. the decimator's per-patch normal fields).
  Normals corner_normals;
  // Light direction in camera coordinates (x right, y up, z towards the viewer); need not be unit.
  Eigen::Vector3d light_in_camera{-0.4, 0.5, 1.0};
  double ambient = 0.15;  // share of light that does not depend on the normal, [0, 1]
  // Light both sides of a face equally (noisy meshes may have faces flipped; a one-sided light would show
  // them black). When off, back faces get only the ambient term.
  bool two_sided = true;
  Eigen::Vector3f background{1.0f, 1.0f, 1.0f};  // RGB in [0, 1]

  // Throws Error naming the field when a value is out of range or sizes do not match `mesh`.
  void Check(const Mesh& mesh) const;
};

// Renders `mesh` (faces with an out-of-range index throw Error; faces of zero area are skipped; NaN vertices
// are skipped). An empty mesh gives a background-only image.
RgbImage RenderMesh(const Mesh& mesh, const RenderOptions& options = {});

// The box of the central `share` of the finite vertices in each axis, share in [0.5, 1] ((1 − share)/2 cut at
// each end; 1: the bounding box): a framing that a few stray vertices far from the rest (a depth image's
// mismatched pixels) do not shrink. Empty when the mesh has no finite vertex.
Eigen::AlignedBox3d CentralBox(const Mesh& mesh, double share);

// A mesh in the frame of the camera that saw it (a depth image's: x right, y down, z forward, as `stereo`,
// `spacetime` and `replay` write them; told by its pixel coordinates: the vertices lie in front, z > 0, on the
// rays of a pinhole at the origin, x/z and y/z linear in the column and the row, R² ≥ 0.99; a range scanner's
// grid is not) is drawn as that camera saw it: orthographic along +z with −y up,
// fitted to CentralBox(mesh, 0.99) so that a few mismatched pixels far behind the scene do not shrink the
// picture. Sets view_direction, up, projection and fit_box and returns true; false (options unchanged) for any
// other mesh.
bool SetCameraFrameView(const NoisyMesh& mesh, RenderOptions* options);

// The framing of a picture of `mesh` and of the meshes made from it (smoothed, decimated), shared by all of them:
// SetCameraFrameView where it applies, else options' own view_direction and up, fitted to the bounding box.
void FitView(const NoisyMesh& mesh, RenderOptions* options);

// RenderOptions::corner_normals from indexed per-corner normals (a decimated mesh's patch normal fields): row
// 3·f + k is corner_normals.normals.row(corner_normals.normal_index(f, k)).
Normals CornerNormalRows(const CornerNormals& corner_normals);

// Area-weighted vertex normals (#V×3, unit; zero rows for isolated vertices or all-degenerate fans).
Normals AreaWeightedVertexNormals(const Mesh& mesh);

// Places images left to right with `gap_px` columns of `background` between them, top-aligned; the height is
// the tallest image's. Empty input gives an empty image.
RgbImage SideBySide(const std::vector<RgbImage>& images, int gap_px = 8,
                    const Eigen::Vector3f& background = Eigen::Vector3f(1.0f, 1.0f, 1.0f));

}  // namespace rangebayes
