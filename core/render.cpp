#include "core/render.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/error.h"

namespace rangebayes {
namespace {

std::uint8_t ToByte(float v) {
  const float c = std::clamp(v, 0.0f, 1.0f);
  return static_cast<std::uint8_t>(std::lround(c * 255.0f));
}

// Orthonormal camera axes: right, up, and back (towards the viewer), so that view space is right-handed.
struct CameraAxes {
  Eigen::Vector3d right, up, back;
};

CameraAxes MakeAxes(const RenderOptions& options) {
  CameraAxes axes;
  // stableNormalized: a direction of 1e200 (or 1e-300) has a norm that overflows (underflows) as a plain sum of
  // squares, and normalized() then gave a zero vector and a blank picture.
  const Eigen::Vector3d forward = options.view_direction.stableNormalized();
  Eigen::Vector3d up = options.up;
  if (!(up.stableNorm() > 0) || std::abs(forward.dot(up.stableNormalized())) > 0.999) {
    // Pick the coordinate axis least aligned with the view direction.
    Eigen::Index k = 0;
    forward.cwiseAbs().minCoeff(&k);
    up = Eigen::Vector3d::Unit(k);
  }
  axes.right = forward.cross(up).normalized();
  axes.up = axes.right.cross(forward).normalized();
  axes.back = -forward;
  return axes;
}

// An image of the given size filled with `background` (channels in [0, 1]).
RgbImage FilledImage(int width, int height, const Eigen::Vector3f& background) {
  RgbImage image(width, height);
  for (int i = 0; i < width * height; ++i) {
    for (int ch = 0; ch < 3; ++ch) image.rgb[static_cast<size_t>(i) * 3 + ch] = ToByte(background[ch]);
  }
  return image;
}

// Throws unless every face refers to vertices in [0, #V).
void CheckFaceIndices(const Mesh& mesh) {
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      RB_CHECK(mesh.F(f, k) >= 0 && mesh.F(f, k) < nv, "render: face ", f, " refers to vertex ", mesh.F(f, k),
               ", but the mesh has ", nv, " vertices");
    }
  }
}

// Centre and radius of the box the view is fitted to (RenderOptions::fit_box, else the bounding box of the
// finite vertices); false when there is none.
bool FitSphere(const Mesh& mesh, const RenderOptions& options, Eigen::Vector3d* centre, double* radius) {
  const Eigen::AlignedBox3d box = options.fit_box.isEmpty() ? CentralBox(mesh, 1.0) : options.fit_box;
  if (box.isEmpty()) return false;
  *centre = box.center();
  *radius = std::max(0.5 * box.diagonal().norm(), 1e-300);
  return true;
}

// Per vertex its view coordinates (x right, y up, depth in front of the camera > 0 for perspective) and its
// projection (NaN behind a perspective camera), with the extent of the finite projections.
struct ViewVertices {
  std::vector<Eigen::Vector3d> view;
  std::vector<Eigen::Vector2d> projected;
  double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x, min_y = min_x, max_y = -min_x;
};

// Projects every vertex; distance is the camera's distance from centre along the view axis (0 orthographic).
ViewVertices ProjectVertices(const Mesh& mesh, const CameraAxes& axes, const Eigen::Vector3d& centre, double radius,
                             double distance, bool perspective) {
  const int nv = mesh.num_vertices();
  ViewVertices out;
  out.view.resize(static_cast<size_t>(nv));
  out.projected.resize(static_cast<size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    const Eigen::Vector3d d = mesh.V.row(v).transpose() - centre;
    Eigen::Vector3d q(d.dot(axes.right), d.dot(axes.up), distance - d.dot(axes.back));
    out.view[static_cast<size_t>(v)] = q;
    Eigen::Vector2d p(q.x(), q.y());
    if (perspective) p = (q.z() > 1e-12 * radius) ? Eigen::Vector2d(q.x() / q.z(), q.y() / q.z())
                                                   : Eigen::Vector2d::Constant(std::nan(""));
    out.projected[static_cast<size_t>(v)] = p;
    if (p.allFinite()) {
      out.min_x = std::min(out.min_x, p.x());
      out.max_x = std::max(out.max_x, p.x());
      out.min_y = std::min(out.min_y, p.y());
      out.max_y = std::max(out.max_y, p.y());
    }
  }
  return out;
}

// Maps projected coordinates to pixels (x right, y down), the given extent centred and scaled into the margins.
struct PixelMap {
  int width = 0, height = 0;
  double scale = 1.0, mid_x = 0.0, mid_y = 0.0;
  Eigen::Vector2d operator()(const Eigen::Vector2d& p) const {
    return Eigen::Vector2d(0.5 * width + (p.x() - mid_x) * scale, 0.5 * height - (p.y() - mid_y) * scale);
  }
};

// The pixel map of the projected extent, or for perspective of the field of view (tan_half = tan(fov / 2)).
PixelMap MakePixelMap(const ViewVertices& extent, const RenderOptions& options, double tan_half, bool perspective) {
  const int width = options.width_px, height = options.height_px;
  double min_x = extent.min_x, max_x = extent.max_x, min_y = extent.min_y, max_y = extent.max_y;
  if (perspective) {
    // Fit the field of view rather than the projected extent, so that the framing does not jump between
    // two renderings of similar meshes.
    min_y = -tan_half;
    max_y = tan_half;
    const double aspect = static_cast<double>(width) / height;
    min_x = -tan_half * aspect;
    max_x = tan_half * aspect;
  }
  const double usable_w = width * (1.0 - 2.0 * options.margin_fraction);
  const double usable_h = height * (1.0 - 2.0 * options.margin_fraction);
  const double extent_x = std::max(max_x - min_x, 1e-300), extent_y = std::max(max_y - min_y, 1e-300);
  PixelMap map;
  map.width = width;
  map.height = height;
  map.scale = std::min(usable_w / extent_x, usable_h / extent_y);
  map.mid_x = 0.5 * (min_x + max_x);
  map.mid_y = 0.5 * (min_y + max_y);
  return map;
}

// Lambert shading of normals given in world space (ToCamera) or camera space (Shade), in [ambient, 1].
struct Shader {
  const RenderOptions& options;
  const CameraAxes& axes;
  Eigen::Vector3d light;  // unit, in camera space
  Eigen::Vector3d ToCamera(const Eigen::Vector3d& n) const {
    return Eigen::Vector3d(n.dot(axes.right), n.dot(axes.up), n.dot(axes.back));
  }
  float Shade(Eigen::Vector3d n_camera) const {
    const double len = n_camera.norm();
    if (!(len > 0)) return static_cast<float>(options.ambient);
    n_camera /= len;
    double lambert = n_camera.dot(light);
    if (options.two_sided) {
      lambert = std::abs(lambert);
    } else if (n_camera.z() < 0) {
      lambert = 0;
    }
    return static_cast<float>(options.ambient + (1.0 - options.ambient) * std::max(0.0, lambert));
  }
};

// What every face of one rendering reads: the projected vertices, the pixel map, the shading and the normals.
struct FaceContext {
  const Mesh& mesh;
  const RenderOptions& options;
  const ViewVertices& vertices;
  const PixelMap& to_pixel;
  const Shader& shader;
  const Normals& vertex_normals;  // per vertex, used when smooth && !use_corners
  bool perspective, smooth, use_corners;
};

// One screen triangle: pixel corners s, depth keys, its colour and its lighting (per corner when smooth).
struct ScreenTriangle {
  Eigen::Vector2d s[3];
  double key[3];
  double area2 = 0.0;
  Eigen::Vector3d corner_n[3];
  float corner_light[3];
  float face_light = 0;
  Eigen::Vector3f color;
};

// Sets up face f for rasterisation; false when a corner is not finite or its screen area is (near) zero.
bool SetUpTriangle(const FaceContext& ctx, int f, ScreenTriangle* t) {
  const Mesh& mesh = ctx.mesh;
  const RenderOptions& options = ctx.options;
  const int idx[3] = {mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
  Eigen::Vector2d* s = t->s;
  bool ok = true;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2d& p = ctx.vertices.projected[static_cast<size_t>(idx[k])];
    const Eigen::Vector3d& q = ctx.vertices.view[static_cast<size_t>(idx[k])];
    if (!p.allFinite() || !q.allFinite()) ok = false;
    s[k] = ctx.to_pixel(p);
    t->key[k] = ctx.perspective ? -1.0 / q.z() : q.z();
  }
  if (!ok) return false;
  t->area2 = (s[1] - s[0]).x() * (s[2] - s[0]).y() - (s[1] - s[0]).y() * (s[2] - s[0]).x();
  if (!(std::abs(t->area2) > 1e-12)) return false;

  const Eigen::Vector3d face_normal = (mesh.V.row(idx[1]) - mesh.V.row(idx[0]))
                                          .transpose()
                                          .cross((mesh.V.row(idx[2]) - mesh.V.row(idx[0])).transpose());
  if (ctx.smooth) {
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d& n = t->corner_n[k];
      n = ctx.use_corners ? Eigen::Vector3d(options.corner_normals.row(3 * static_cast<Eigen::Index>(f) + k))
                          : Eigen::Vector3d(ctx.vertex_normals.row(idx[k]));
      if (!n.allFinite() || n.norm() == 0) n = face_normal;
      n = ctx.shader.ToCamera(n);
      t->corner_light[k] = ctx.shader.Shade(n);
    }
  } else {
    t->face_light = ctx.shader.Shade(ctx.shader.ToCamera(face_normal));
  }
  t->color = options.face_colors.rows() > 0 ? Eigen::Vector3f(options.face_colors.row(f)) : options.base_color;
  return true;
}

// Writes the pixels of t that pass the depth test (smaller key is closer) into zbuffer and image.
void FillTriangle(const FaceContext& ctx, const ScreenTriangle& t, std::vector<double>* zbuffer, RgbImage* image) {
  const int width = ctx.options.width_px, height = ctx.options.height_px;
  const Eigen::Vector2d* s = t.s;
  // Clamped to the image before the conversion to int (a vertex outside RenderOptions::fit_box may lie far off).
  auto pixel = [](double v, int size) { return static_cast<int>(std::clamp(v, -1.0, static_cast<double>(size))); };
  const int x0 = std::max(0, pixel(std::floor(std::min({s[0].x(), s[1].x(), s[2].x()})), width));
  const int x1 = std::min(width - 1, pixel(std::ceil(std::max({s[0].x(), s[1].x(), s[2].x()})), width));
  const int y0 = std::max(0, pixel(std::floor(std::min({s[0].y(), s[1].y(), s[2].y()})), height));
  const int y1 = std::min(height - 1, pixel(std::ceil(std::max({s[0].y(), s[1].y(), s[2].y()})), height));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d p(x + 0.5, y + 0.5);
      // Barycentric weights of the pixel centre; the small tolerance closes cracks between faces.
      double w[3];
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d& a = s[(k + 1) % 3];
        const Eigen::Vector2d& b = s[(k + 2) % 3];
        w[k] = ((b - a).x() * (p - a).y() - (b - a).y() * (p - a).x()) / t.area2;
      }
      if (w[0] < -1e-9 || w[1] < -1e-9 || w[2] < -1e-9) continue;
      const double z = w[0] * t.key[0] + w[1] * t.key[1] + w[2] * t.key[2];
      double& depth = (*zbuffer)[static_cast<size_t>(y) * width + x];
      if (!(z < depth)) continue;
      depth = z;
      float intensity = t.face_light;
      if (ctx.smooth) {
        intensity = ctx.shader.Shade(w[0] * t.corner_n[0] + w[1] * t.corner_n[1] + w[2] * t.corner_n[2]);
        if (!std::isfinite(intensity)) intensity = t.corner_light[0];
      }
      std::uint8_t* px = image->at(x, y);
      for (int ch = 0; ch < 3; ++ch) px[ch] = ToByte(t.color[ch] * intensity);
    }
  }
}

}  // namespace

void RenderOptions::Check(const Mesh& mesh) const {
  RB_CHECK(width_px >= 1 && width_px <= 16384, "render: width_px ", width_px, " is outside [1, 16384]");
  RB_CHECK(height_px >= 1 && height_px <= 16384, "render: height_px ", height_px, " is outside [1, 16384]");
  RB_CHECK(view_direction.allFinite() && view_direction.stableNorm() > 0,
           "render: view_direction must be nonzero and finite");
  RB_CHECK(field_of_view_deg > 0 && field_of_view_deg < 170, "render: field_of_view_deg ", field_of_view_deg,
           " is outside (0, 170)");
  RB_CHECK(margin_fraction >= 0 && margin_fraction <= 0.45, "render: margin_fraction ", margin_fraction,
           " is outside [0, 0.45]");
  RB_CHECK(ambient >= 0 && ambient <= 1, "render: ambient ", ambient, " is outside [0, 1]");
  RB_CHECK(face_colors.rows() == 0 || face_colors.rows() == mesh.num_faces(), "render: face_colors has ",
           face_colors.rows(), " rows, the mesh has ", mesh.num_faces(), " faces");
  RB_CHECK(corner_normals.rows() == 0 || corner_normals.rows() == 3 * static_cast<Eigen::Index>(mesh.num_faces()),
           "render: corner_normals has ", corner_normals.rows(), " rows, expected 3 × ", mesh.num_faces(),
           " faces");
  RB_CHECK(light_in_camera.norm() > 0, "render: light_in_camera must be nonzero");
}

Normals CornerNormalRows(const CornerNormals& corner_normals) {
  const Eigen::Index faces = corner_normals.normal_index.rows();
  Normals rows(3 * faces, 3);
  for (Eigen::Index f = 0; f < faces; ++f) {
    for (int k = 0; k < 3; ++k) rows.row(3 * f + k) = corner_normals.normals.row(corner_normals.normal_index(f, k));
  }
  return rows;
}

Normals AreaWeightedVertexNormals(const Mesh& mesh) {
  Normals normals = Normals::Zero(mesh.num_vertices(), 3);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int a = mesh.F(f, 0), b = mesh.F(f, 1), c = mesh.F(f, 2);
    RB_CHECK(a >= 0 && b >= 0 && c >= 0 && a < mesh.num_vertices() && b < mesh.num_vertices() &&
                 c < mesh.num_vertices(),
             "face ", f, " refers to a vertex outside [0, ", mesh.num_vertices(), ")");
    const Eigen::Vector3d cross =
        (mesh.V.row(b) - mesh.V.row(a)).transpose().cross((mesh.V.row(c) - mesh.V.row(a)).transpose());
    if (!cross.allFinite()) continue;
    // |cross| is twice the area: summing unnormalised cross products weights by area.
    for (int v : {a, b, c}) normals.row(v) += cross.transpose();
  }
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const double n = normals.row(v).norm();
    if (n > 0) normals.row(v) /= n;
  }
  return normals;
}

RgbImage RenderMesh(const Mesh& mesh, const RenderOptions& options) {
  options.Check(mesh);
  const int width = options.width_px, height = options.height_px;
  RgbImage image = FilledImage(width, height, options.background);
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  if (nv == 0 || nf == 0) return image;
  CheckFaceIndices(mesh);

  Eigen::Vector3d centre;
  double radius = 0.0;
  if (!FitSphere(mesh, options, &centre, &radius)) return image;

  const CameraAxes axes = MakeAxes(options);
  const bool perspective = options.projection == Projection::kPerspective;
  const double tan_half = std::tan(0.5 * options.field_of_view_deg * M_PI / 180.0);
  // Perspective: camera on the view axis far enough for the bounding sphere to fit the field of view.
  const double distance = perspective ? radius / std::sin(0.5 * options.field_of_view_deg * M_PI / 180.0) * 1.05
                                      : 0.0;
  ViewVertices vertices = ProjectVertices(mesh, axes, centre, radius, distance, perspective);
  if (!perspective && !options.fit_box.isEmpty()) {
    // The extent of the box's corners, not of the vertices (perspective fits the field of view either way).
    vertices.min_x = vertices.min_y = std::numeric_limits<double>::infinity();
    vertices.max_x = vertices.max_y = -vertices.min_x;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d d = options.fit_box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)) - centre;
      vertices.min_x = std::min(vertices.min_x, d.dot(axes.right));
      vertices.max_x = std::max(vertices.max_x, d.dot(axes.right));
      vertices.min_y = std::min(vertices.min_y, d.dot(axes.up));
      vertices.max_y = std::max(vertices.max_y, d.dot(axes.up));
    }
  }
  if (!(vertices.min_x <= vertices.max_x)) return image;
  const PixelMap to_pixel = MakePixelMap(vertices, options, tan_half, perspective);

  Normals vertex_normals;
  const bool smooth = options.shading == Shading::kSmooth;
  const bool use_corners = smooth && options.corner_normals.rows() > 0;
  if (smooth && !use_corners) {
    vertex_normals = (mesh.N.rows() == nv) ? mesh.N : AreaWeightedVertexNormals(mesh);
  }
  const Shader shader{options, axes, options.light_in_camera.normalized()};
  const FaceContext ctx{mesh, options, vertices, to_pixel, shader, vertex_normals, perspective, smooth, use_corners};

  // Depth key per pixel, smaller is closer: view depth (orthographic) or −1/depth (perspective, linear in
  // screen space).
  std::vector<double> zbuffer(static_cast<size_t>(width) * height, std::numeric_limits<double>::infinity());
  for (int f = 0; f < nf; ++f) {
    ScreenTriangle t;
    if (SetUpTriangle(ctx, f, &t)) FillTriangle(ctx, t, &zbuffer, &image);
  }
  return image;
}

Eigen::AlignedBox3d CentralBox(const Mesh& mesh, double share) {
  RB_CHECK(share >= 0.5 && share <= 1, "CentralBox: share ", share, " is outside [0.5, 1]");
  Eigen::AlignedBox3d box;  // empty
  if (share == 1.0) {
    for (int v = 0; v < mesh.num_vertices(); ++v) {
      if (mesh.V.row(v).allFinite()) box.extend(mesh.V.row(v).transpose());
    }
    return box;
  }
  std::vector<double> values;
  values.reserve(static_cast<size_t>(mesh.num_vertices()));
  for (int axis = 0; axis < 3; ++axis) {
    values.clear();
    for (int v = 0; v < mesh.num_vertices(); ++v) {
      if (mesh.V.row(v).allFinite()) values.push_back(mesh.V(v, axis));
    }
    if (values.empty()) return Eigen::AlignedBox3d();
    // Nearest-rank quantiles (1 − share)/2 and (1 + share)/2.
    const double last = static_cast<double>(values.size() - 1);
    const auto lo = static_cast<std::ptrdiff_t>(std::floor(0.5 * (1.0 - share) * last));
    const auto hi = static_cast<std::ptrdiff_t>(std::ceil(0.5 * (1.0 + share) * last));
    std::nth_element(values.begin(), values.begin() + lo, values.end());
    box.min()(axis) = values[static_cast<size_t>(lo)];
    std::nth_element(values.begin(), values.begin() + hi, values.end());
    box.max()(axis) = values[static_cast<size_t>(hi)];
  }
  return box;
}

bool SetCameraFrameView(const NoisyMesh& noisy, RenderOptions* options) {
  const Mesh& mesh = noisy.mesh;
  if (noisy.pixel.rows() != mesh.num_vertices() || mesh.num_vertices() == 0) return false;
  // A pinhole at the origin looking along +z: x/z = a·u + b and y/z = c·v + d with a, c > 0, to within rounding
  // and a few mismatched pixels (R² ≥ 0.99 each). Sums of the two least-squares fits over the vertices in front.
  struct Fit {
    double n = 0, s = 0, t = 0, ss = 0, st = 0, tt = 0;
    void Add(double pixel, double ratio) {
      n += 1;
      s += pixel;
      t += ratio;
      ss += pixel * pixel;
      st += pixel * ratio;
      tt += ratio * ratio;
    }
    // Slope > 0 and R² ≥ 0.99.
    bool Holds() const {
      const double var_s = ss - s * s / n, var_t = tt - t * t / n, cov = st - s * t / n;
      return n >= 3 && var_s > 0 && var_t > 0 && cov > 0 && cov * cov >= 0.99 * var_s * var_t;
    }
  } column, row;
  int behind = 0;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    if (!noisy.pixel.row(v).allFinite() || !mesh.V.row(v).allFinite()) continue;
    const double z = mesh.V(v, 2);
    if (!(z > 0)) {
      ++behind;
      continue;
    }
    column.Add(noisy.pixel(v, 0), mesh.V(v, 0) / z);
    row.Add(noisy.pixel(v, 1), mesh.V(v, 1) / z);
  }
  if (!(column.n > 2 * behind) || !column.Holds() || !row.Holds()) return false;
  options->view_direction = Eigen::Vector3d(0, 0, 1);
  options->up = Eigen::Vector3d(0, -1, 0);
  options->projection = Projection::kOrthographic;
  options->fit_box = CentralBox(mesh, 0.99);
  return true;
}

void FitView(const NoisyMesh& mesh, RenderOptions* options) {
  if (!SetCameraFrameView(mesh, options)) options->fit_box = CentralBox(mesh.mesh, 1.0);
}

RgbImage SideBySide(const std::vector<RgbImage>& images, int gap_px, const Eigen::Vector3f& background) {
  RB_CHECK(gap_px >= 0, "SideBySide: gap_px ", gap_px, " is negative");
  if (images.empty()) return RgbImage();
  int width = 0, height = 0;
  for (const RgbImage& im : images) {
    width += im.width;
    height = std::max(height, im.height);
  }
  width += gap_px * static_cast<int>(images.size() - 1);
  RgbImage out = FilledImage(width, height, background);
  int x_offset = 0;
  for (const RgbImage& im : images) {
    for (int y = 0; y < im.height; ++y) {
      std::copy(im.at(0, y), im.at(0, y) + static_cast<size_t>(im.width) * 3, out.at(x_offset, y));
    }
    x_offset += im.width + gap_px;
  }
  return out;
}

}  // namespace rangebayes
