#include "stereo/synth.h"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <random>

#include "capture/recording.h"
#include "core/error.h"
#include "core/files.h"
#include "stereo/pfm.h"

namespace rangebayes {

SynthScene ParseSynthScene(const std::string& name) {
  if (name == "plane") return SynthScene::kPlane;
  if (name == "planes") return SynthScene::kPlanes;
  if (name == "box") return SynthScene::kBox;
  if (name == "sphere") return SynthScene::kSphere;
  if (name == "cylinder") return SynthScene::kCylinder;
  if (name == "stairs") return SynthScene::kStairs;
  RB_FAIL("unknown scene '", name, "' (plane, planes, box, sphere, cylinder, stairs)");
}

SynthPattern ParseSynthPattern(const std::string& name) {
  if (name == "random") return SynthPattern::kRandom;
  if (name == "graycode") return SynthPattern::kGrayCode;
  RB_FAIL("unknown pattern '", name, "' (random, graycode)");
}

std::string ToString(SynthScene scene) {
  switch (scene) {
    case SynthScene::kPlane: return "plane";
    case SynthScene::kPlanes: return "planes";
    case SynthScene::kBox: return "box";
    case SynthScene::kSphere: return "sphere";
    case SynthScene::kCylinder: return "cylinder";
    case SynthScene::kStairs: return "stairs";
  }
  return "?";
}

std::string ToString(SynthPattern pattern) { return pattern == SynthPattern::kRandom ? "random" : "graycode"; }

void SynthOptions::Check() const {
  RB_CHECK(frames >= 1 && frames <= 256, "frames ", frames, " is outside 1–256");
  RB_CHECK(image_noise_gray >= 0.0 && image_noise_gray <= 100.0, "image noise ", image_noise_gray,
           " is outside 0–100 grey levels");
  RB_CHECK(width >= 16 && width <= 4096 && height >= 16 && height <= 4096, "image size ", width, "x", height,
           " is outside 16–4096");
  RB_CHECK(focal_px >= 0.0, "focal_px must be ≥ 0");
  RB_CHECK(baseline_m > 0.0, "baseline_m must be positive");
  RB_CHECK(pattern_cell_px >= 0.5 && pattern_cell_px <= 64.0, "pattern_cell_px ", pattern_cell_px,
           " is outside 0.5–64");
  RB_CHECK(std::abs(projector_roll_deg) <= 45.0, "projector_roll_deg ", projector_roll_deg, " is outside ±45");
  RB_CHECK(optics_blur_px >= 0.0 && optics_blur_px <= 5.0, "optics_blur_px ", optics_blur_px, " is outside 0–5");
  RB_CHECK(ambient >= 0.0 && ambient <= 1.0, "ambient ", ambient, " is outside 0–1");
  RB_CHECK(supersample >= 1 && supersample <= 8, "supersample ", supersample, " is outside 1–8");
  RB_CHECK(pixel_jitter_px >= 0.0 && pixel_jitter_px <= 2.0, "pixel_jitter_px ", pixel_jitter_px,
           " is outside 0–2");
  RB_CHECK(pixel_jitter_cell_px >= 1.0 && pixel_jitter_cell_px <= 256.0, "pixel_jitter_cell_px ",
           pixel_jitter_cell_px, " is outside 1–256");
}

namespace {

using Eigen::Vector3d;
constexpr double kNoHit = std::numeric_limits<double>::infinity();

struct Hit {
  double t = kNoHit;
  Vector3d normal = Vector3d::Zero();
  double albedo = 0.0;
};

// Rays are o + t·d with d not normalised (camera rays have d.z = 1, so t is the depth Z).
struct Primitive {
  enum Kind { kPlane, kBox, kSphere, kCylinder } kind = kPlane;
  Vector3d center = Vector3d::Zero();  // plane: a point on it
  Vector3d normal = Vector3d::UnitZ();  // plane normal
  Vector3d half = Vector3d::Ones();     // box half extents
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // box: world_from_box
  double radius = 0.0;                  // sphere, cylinder
  double y_min = 0.0, y_max = 0.0;      // cylinder (vertical axis through center)
  double albedo = 0.8;

  void Intersect(const Vector3d& o, const Vector3d& d, double t_min, Hit* hit) const {
    switch (kind) {
      case kPlane: {
        const double nd = normal.dot(d);
        if (std::abs(nd) < 1e-12) return;
        const double t = normal.dot(center - o) / nd;
        if (t > t_min && t < hit->t) *hit = {t, nd < 0 ? normal : Vector3d(-normal), albedo};
        return;
      }
      case kSphere: {
        const Vector3d oc = o - center;
        const double a = d.squaredNorm(), b = 2.0 * d.dot(oc), c = oc.squaredNorm() - radius * radius;
        const double disc = b * b - 4 * a * c;
        if (disc < 0) return;
        const double sq = std::sqrt(disc);
        for (double t : {(-b - sq) / (2 * a), (-b + sq) / (2 * a)}) {
          if (t > t_min && t < hit->t) {
            *hit = {t, (o + t * d - center).normalized(), albedo};
            return;
          }
        }
        return;
      }
      case kBox: {
        const Vector3d ob = rotation.transpose() * (o - center), db = rotation.transpose() * d;
        double t0 = -kNoHit, t1 = kNoHit;
        int axis0 = -1, axis1 = -1;
        for (int k = 0; k < 3; ++k) {
          if (std::abs(db[k]) < 1e-15) {
            if (std::abs(ob[k]) > half[k]) return;
            continue;
          }
          double ta = (-half[k] - ob[k]) / db[k], tb = (half[k] - ob[k]) / db[k];
          if (ta > tb) std::swap(ta, tb);
          if (ta > t0) { t0 = ta; axis0 = k; }
          if (tb < t1) { t1 = tb; axis1 = k; }
        }
        if (t0 > t1) return;
        const double t = t0 > t_min ? t0 : t1;
        const int axis = t0 > t_min ? axis0 : axis1;
        if (!(t > t_min) || t >= hit->t || axis < 0) return;
        Vector3d n = Vector3d::Zero();
        n[axis] = (ob[axis] + t * db[axis]) > 0 ? 1.0 : -1.0;
        *hit = {t, rotation * n, albedo};
        return;
      }
      case kCylinder: {
        const double ox = o.x() - center.x(), oz = o.z() - center.z();
        const double a = d.x() * d.x() + d.z() * d.z();
        if (a > 1e-15) {
          const double b = 2 * (ox * d.x() + oz * d.z()), c = ox * ox + oz * oz - radius * radius;
          const double disc = b * b - 4 * a * c;
          if (disc >= 0) {
            const double sq = std::sqrt(disc);
            for (double t : {(-b - sq) / (2 * a), (-b + sq) / (2 * a)}) {
              const double y = o.y() + t * d.y();
              if (t > t_min && t < hit->t && y >= y_min && y <= y_max) {
                const Vector3d p = o + t * d;
                *hit = {t, Vector3d(p.x() - center.x(), 0, p.z() - center.z()).normalized(), albedo};
                break;
              }
            }
          }
        }
        if (std::abs(d.y()) > 1e-15) {
          for (double yc : {y_min, y_max}) {
            const double t = (yc - o.y()) / d.y();
            const Vector3d p = o + t * d;
            const double rx = p.x() - center.x(), rz = p.z() - center.z();
            if (t > t_min && t < hit->t && rx * rx + rz * rz <= radius * radius) {
              *hit = {t, Vector3d(0, yc == y_min ? -1.0 : 1.0, 0), albedo};
            }
          }
        }
        return;
      }
    }
  }
};

Primitive Plane(const Vector3d& point, const Vector3d& normal, double albedo) {
  Primitive p;
  p.kind = Primitive::kPlane;
  p.center = point;
  p.normal = normal.normalized();
  p.albedo = albedo;
  return p;
}

Primitive Box(const Vector3d& center, const Vector3d& half, double yaw_deg, double albedo) {
  Primitive p;
  p.kind = Primitive::kBox;
  p.center = center;
  p.half = half;
  p.rotation = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Vector3d::UnitY()).toRotationMatrix();
  p.albedo = albedo;
  return p;
}

// Camera frame: x right, y down, z forward; the floor is the plane y = +0.35 m.
std::vector<Primitive> BuildScene(SynthScene scene) {
  std::vector<Primitive> s;
  const Primitive wall = Plane({0, 0, 1.5}, {0.15, 0.0, -1.0}, 0.7);
  const Primitive floor = Plane({0, 0.35, 0}, {0, -1, 0}, 0.6);
  switch (scene) {
    case SynthScene::kPlane:
      s.push_back(Plane({0, 0, 1.0}, {0, 0, -1}, 0.8));
      break;
    case SynthScene::kPlanes:
      s = {wall, floor, Box({-0.15, -0.02, 0.95}, {0.22, 0.2, 0.005}, 0.0, 0.9)};
      break;
    case SynthScene::kBox:
      s = {wall, floor, Box({0.0, 0.2, 1.05}, {0.2, 0.15, 0.15}, 30.0, 0.9)};
      break;
    case SynthScene::kSphere: {
      s = {wall, floor};
      Primitive sphere;
      sphere.kind = Primitive::kSphere;
      sphere.center = {0.0, 0.0, 1.0};
      sphere.radius = 0.25;
      sphere.albedo = 0.9;
      s.push_back(sphere);
      break;
    }
    case SynthScene::kCylinder: {
      s = {wall, floor};
      Primitive c;
      c.kind = Primitive::kCylinder;
      c.center = {0.0, 0.0, 1.05};
      c.radius = 0.18;
      c.y_min = -0.3;
      c.y_max = 0.35;
      c.albedo = 0.9;
      s.push_back(c);
      break;
    }
    case SynthScene::kStairs:
      s = {wall, floor};
      for (int i = 0; i < 4; ++i) {
        const double top = 0.35 - 0.1 * (i + 1);
        const double z0 = 0.8 + 0.14 * i;
        s.push_back(Box({0.0, 0.5 * (top + 0.35), 0.5 * (z0 + 1.45)}, {0.35, 0.5 * (0.35 - top), 0.5 * (1.45 - z0)},
                        0.0, 0.85));
      }
      break;
  }
  return s;
}

Hit CastRay(const std::vector<Primitive>& scene, const Vector3d& o, const Vector3d& d, double t_min) {
  Hit hit;
  for (const auto& p : scene) p.Intersect(o, d, t_min, &hit);
  return hit;
}

// What one sub-sample sees, independent of the pattern: where it lands in the projector and how bright a
// fully lit projector pixel makes it.
struct Sample {
  float pu = 0, pv = 0;  // projector pixel coordinates
  float gain = 0;        // albedo · cos(incidence) when lit, 0 when in shadow or nothing was hit
};

struct Projector {
  Vector3d position;
  double f = 0, cx = 0, cy = 0;  // in projector pixels
  double cos_roll = 1, sin_roll = 0;  // rotation of the projector image about its axis
};

// Smooth random pixel offsets δ(u, v) in left-image coordinates: N(0, σ²) values on a grid of `cell` pixels,
// bilinearly interpolated with the weights renormalised by sqrt(Σ w²), so every point's δ is exactly
// N(0, σ²) per component (plain interpolation would shrink the variance between the grid nodes).
class JitterField {
 public:
  JitterField() = default;
  JitterField(double sigma_px, double cell_px, int width, int height, std::uint64_t seed) : cell_(cell_px) {
    gw_ = static_cast<int>(std::ceil(width / cell_px)) + 2;
    gh_ = static_cast<int>(std::ceil(height / cell_px)) + 2;
    std::mt19937_64 rng(seed * 0x2545F4914F6CDD1DULL + 0x5851F42D4C957F2DULL);
    std::normal_distribution<double> gauss(0.0, sigma_px);
    nodes_.resize(static_cast<size_t>(gw_) * gh_);
    for (auto& n : nodes_) n = Eigen::Vector2d(gauss(rng), gauss(rng));
  }
  bool empty() const { return nodes_.empty(); }
  Eigen::Vector2d At(double u, double v) const {
    const double x = std::clamp(u / cell_, 0.0, gw_ - 1.001), y = std::clamp(v / cell_, 0.0, gh_ - 1.001);
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const double fx = x - x0, fy = y - y0;
    const double w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
    const Eigen::Vector2d* r0 = nodes_.data() + static_cast<size_t>(y0) * gw_ + x0;
    const Eigen::Vector2d* r1 = r0 + gw_;
    return (w00 * r0[0] + w10 * r0[1] + w01 * r1[0] + w11 * r1[1]) /
           std::sqrt(w00 * w00 + w10 * w10 + w01 * w01 + w11 * w11);
  }

 private:
  double cell_ = 1.0;
  int gw_ = 0, gh_ = 0;
  std::vector<Eigen::Vector2d> nodes_;
};

// The ray (origin, direction with z = 1) that camera sample (su, sv) is rendered from. Without jitter, the
// ray through the sample. With jitter, the left camera's ray passes through (su, sv) + δ(su, sv); the right
// camera's through (su, sv) + δ(ul, sv), where ul is the left-image position of the surface point it sees
// (found by fixed-point iteration, since that point itself moves with δ): both cameras then see the point
// with the same δ, so the correspondence keeps its true disparity.
Vector3d SampleRay(const std::vector<Primitive>& scene, const JitterField& jitter, bool right_camera,
                   const Vector3d& camera_center, double f, double cx, double cy, double su, double sv) {
  Vector3d d((su - cx) / f, (sv - cy) / f, 1.0);
  if (jitter.empty()) return d;
  if (!right_camera) {
    const Eigen::Vector2d delta = jitter.At(su, sv);
    return Vector3d((su + delta.x() - cx) / f, (sv + delta.y() - cy) / f, 1.0);
  }
  Eigen::Vector2d delta = Eigen::Vector2d::Zero();
  for (int iter = 0; iter < 4; ++iter) {
    const Hit hit = CastRay(scene, camera_center, d, 1e-6);
    if (!std::isfinite(hit.t)) return d;
    const Vector3d p = camera_center + hit.t * d;
    // Left-image position of p without jitter, minus the δ that the left camera adds there.
    const double ul = f * p.x() / p.z() + cx - delta.x();
    delta = jitter.At(ul, sv);
    d = Vector3d((su + delta.x() - cx) / f, (sv + delta.y() - cy) / f, 1.0);
  }
  return d;
}

std::vector<Sample> GeometrySamples(const std::vector<Primitive>& scene, const Projector& proj,
                                   const Vector3d& camera_center, double f, double cx, double cy, int w, int h,
                                   int ss, const JitterField& jitter, bool right_camera) {
  std::vector<Sample> samples(static_cast<size_t>(w) * h * ss * ss);
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      for (int j = 0; j < ss; ++j) {
        for (int i = 0; i < ss; ++i) {
          const double su = u + (i + 0.5) / ss - 0.5, sv = v + (j + 0.5) / ss - 0.5;
          const Vector3d d = SampleRay(scene, jitter, right_camera, camera_center, f, cx, cy, su, sv);
          Sample& s = samples[((static_cast<size_t>(v) * w + u) * ss + j) * ss + i];
          const Hit hit = CastRay(scene, camera_center, d, 1e-6);
          if (!std::isfinite(hit.t)) continue;
          const Vector3d p = camera_center + hit.t * d;
          const Vector3d to_proj = proj.position - p;
          const double cos_in = hit.normal.dot(to_proj.normalized());
          if (cos_in <= 0.0) continue;
          // Shadow: the projector's ray towards p must reach p first.
          const Hit from_proj = CastRay(scene, proj.position, p - proj.position, 1e-9);
          if (from_proj.t < 1.0 - 1e-7) continue;
          if (p.z() - proj.position.z() <= 1e-9) continue;
          const double xn = (p.x() - proj.position.x()) / (p.z() - proj.position.z());
          const double yn = (p.y() - proj.position.y()) / (p.z() - proj.position.z());
          s.pu = static_cast<float>(proj.f * (proj.cos_roll * xn - proj.sin_roll * yn) + proj.cx);
          s.pv = static_cast<float>(proj.f * (proj.sin_roll * xn + proj.cos_roll * yn) + proj.cy);
          s.gain = static_cast<float>(hit.albedo * cos_in);
        }
      }
    }
  });
  return samples;
}

// The projected image of one frame as a function of projector coordinates, values in [0, 1].
class PatternImage {
 public:
  PatternImage(SynthPattern kind, int frame, int frames, int width, int height, std::uint64_t seed)
      : kind_(kind), width_(width), height_(height) {
    if (kind == SynthPattern::kRandom) {
      std::mt19937_64 rng(seed * 1000003ULL + static_cast<std::uint64_t>(frame) * 7919ULL + 17ULL);
      std::uniform_real_distribution<float> uni(0.0f, 1.0f);
      values_.resize(static_cast<size_t>(width) * height);
      for (auto& v : values_) v = uni(rng);
      pattern_id_ = frame;
    } else {
      bits_ = 1;
      while ((1 << bits_) < width) ++bits_;
      // Frames use the last `frames` patterns of the sequence bit 0, ~bit 0, bit 1, ~bit 1, ... (coarsest
      // first), so a short sequence keeps the finest stripes, which are the ones that carry disparity.
      const int total = 2 * bits_;
      const int index = (total - std::min(frames, total) + frame) % total;
      bit_ = index / 2;
      inverted_ = index % 2 == 1;
      pattern_id_ = index;
    }
  }

  float operator()(float pu, float pv) const {
    if (kind_ == SynthPattern::kRandom) {
      // Bilinear interpolation of random cell values: a band-limited texture.
      const float x = std::clamp(pu - 0.5f, 0.0f, static_cast<float>(width_ - 1) - 1e-3f);
      const float y = std::clamp(pv - 0.5f, 0.0f, static_cast<float>(height_ - 1) - 1e-3f);
      const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
      const float fx = x - x0, fy = y - y0;
      const float* r0 = values_.data() + static_cast<size_t>(y0) * width_ + x0;
      const float* r1 = r0 + width_;
      return (1 - fy) * ((1 - fx) * r0[0] + fx * r0[1]) + fy * ((1 - fx) * r1[0] + fx * r1[1]);
    }
    const int column = std::clamp(static_cast<int>(std::floor(pu)), 0, width_ - 1);
    const int gray = column ^ (column >> 1);
    const int bit = (gray >> (bits_ - 1 - bit_)) & 1;
    return static_cast<float>(inverted_ ? 1 - bit : bit);
  }
  int pattern_id() const { return pattern_id_; }

 private:
  SynthPattern kind_;
  int width_, height_;
  std::vector<float> values_;
  int bits_ = 0, bit_ = 0;
  bool inverted_ = false;
  int pattern_id_ = 0;
};

cv::Mat Shade(const std::vector<Sample>& samples, const PatternImage& pattern, int w, int h, int ss, double ambient,
              double blur_px, double noise, std::uint64_t seed) {
  // Radiance at the sub-samples, the lens blur on that fine grid, then the pixel area and the noise: blurring
  // before the pixels integrate is what keeps a fine pattern from aliasing as it does in a real camera.
  cv::Mat fine(h * ss, w * ss, CV_32F);
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const Sample* s = samples.data() + (static_cast<size_t>(v) * w + u) * ss * ss;
      for (int j = 0; j < ss; ++j) {
        float* row = fine.ptr<float>(v * ss + j) + u * ss;
        for (int i = 0; i < ss; ++i) {
          const Sample& k = s[j * ss + i];
          row[i] = k.gain > 0.0f ? k.gain * pattern(k.pu, k.pv) : 0.0f;
        }
      }
    }
  });
  if (blur_px > 0.0) cv::GaussianBlur(fine, fine, cv::Size(), blur_px * ss, blur_px * ss, cv::BORDER_REFLECT);
  cv::Mat pixels;
  cv::resize(fine, pixels, cv::Size(w, h), 0, 0, cv::INTER_AREA);
  cv::Mat image(h, w, CV_8U);
  tbb::parallel_for(0, h, [&](int v) {
    // One generator per row and frame keeps the noise deterministic under any thread schedule.
    std::mt19937_64 rng(seed ^ (0x9E3779B97F4A7C15ULL * static_cast<std::uint64_t>(v + 1)));
    std::normal_distribution<double> gauss(0.0, 1.0);
    std::uint8_t* out = image.ptr<std::uint8_t>(v);
    const float* in = pixels.ptr<float>(v);
    for (int u = 0; u < w; ++u) {
      const double value = 255.0 * (ambient + (1.0 - ambient) * in[u]) + noise * gauss(rng);
      out[u] = static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  });
  return image;
}

// The scene's ground truth and rig (a recording without frames) and what the frames are shaded from.
struct SynthGeometry {
  SynthRecording rec;
  std::vector<Sample> left, right;  // supersamples of each camera's pixels
  int pattern_width = 0, pattern_height = 0;
};

SynthGeometry BuildGeometry(const SynthOptions& options) {
  options.Check();
  const int w = options.width, h = options.height, ss = options.supersample;
  const double f = options.focal_px > 0.0 ? options.focal_px : static_cast<double>(w);
  const double cx = 0.5 * (w - 1), cy = 0.5 * (h - 1);
  const double B = options.baseline_m;
  const std::vector<Primitive> scene = BuildScene(options.scene);

  SynthGeometry g;
  SynthRecording& rec = g.rec;
  rec.intrinsics = {f, f, cx, cy, w, h};
  StereoRig& rig = rec.rig;
  rig.width = w;
  rig.height = h;
  rig.K_left << f, 0, cx, 0, f, cy, 0, 0, 1;
  rig.K_right = rig.K_left;
  rig.t_right_from_left_m = Vector3d(-B, 0, 0);
  rig.is_rectified = true;
  rig.P1.setZero();
  rig.P1.leftCols<3>() = rig.K_left;
  rig.P2 = rig.P1;
  rig.P2(0, 3) = -f * B;
  rig.Q.setZero();
  rig.Q(0, 0) = rig.Q(1, 1) = 1.0;
  rig.Q(0, 3) = -cx;
  rig.Q(1, 3) = -cy;
  rig.Q(2, 3) = f;
  rig.Q(3, 2) = 1.0 / B;

  // Projector half way between the cameras; its pixels are pattern_cell_px camera pixels wide at the centre.
  Projector proj;
  proj.position = Vector3d(0.5 * B, 0, 0);
  proj.f = f / options.pattern_cell_px;
  // A projector whose pixel grid lines up with the cameras' (no roll, whole-pixel cells) puts every
  // window's texture at the same sub-pixel phase, which biases sub-pixel matching far more than any real
  // setup does; a real projector is never aligned that exactly.
  proj.cos_roll = std::cos(options.projector_roll_deg * M_PI / 180.0);
  proj.sin_roll = std::sin(options.projector_roll_deg * M_PI / 180.0);
  const int pw = static_cast<int>(std::ceil(1.3 * w / options.pattern_cell_px)) + 2;
  const int ph = static_cast<int>(std::ceil(1.3 * h / options.pattern_cell_px)) + 2;
  proj.cx = 0.5 * pw;
  proj.cy = 0.5 * ph;
  g.pattern_width = pw;
  g.pattern_height = ph;

  const JitterField jitter = options.pixel_jitter_px > 0.0
                                 ? JitterField(options.pixel_jitter_px, options.pixel_jitter_cell_px, w, h, options.seed)
                                 : JitterField();
  g.left = GeometrySamples(scene, proj, Vector3d::Zero(), f, cx, cy, w, h, ss, jitter, /*right_camera=*/false);
  g.right = GeometrySamples(scene, proj, Vector3d(B, 0, 0), f, cx, cy, w, h, ss, jitter, /*right_camera=*/true);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  rec.depth_m.create(h, w, CV_32F);
  rec.disparity_px.create(h, w, CV_32F);
  if (!jitter.empty()) rec.pixel_jitter_px.create(h, w, CV_32FC2);
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const Vector3d ray = SampleRay(scene, jitter, /*right_camera=*/false, Vector3d::Zero(), f, cx, cy, u, v);
      if (!jitter.empty()) {
        rec.pixel_jitter_px.at<cv::Vec2f>(v, u) =
            cv::Vec2f(static_cast<float>(ray.x() * f + cx - u), static_cast<float>(ray.y() * f + cy - v));
      }
      const Hit hit = CastRay(scene, Vector3d::Zero(), ray, 1e-6);
      const bool ok = std::isfinite(hit.t) && hit.t > 0.0;
      rec.depth_m.at<float>(v, u) = ok ? static_cast<float>(hit.t) : nan;
      rec.disparity_px.at<float>(v, u) = ok ? static_cast<float>(f * B / hit.t) : nan;
    }
  });
  // The scene's disparities must leave it in view of both cameras: at d ≥ the width no pixel of the left image
  // is seen by the right camera (a --baseline 5 at 64 px wide gave 198–400 px and an empty recording).
  double lo = 0, hi = 0;
  cv::minMaxLoc(rec.disparity_px, &lo, &hi, nullptr, nullptr, rec.disparity_px == rec.disparity_px);
  RB_CHECK(hi < w, "synth: the scene's disparities reach ", hi, " px at ", w,
           " px wide: no pixel is seen by both "
           "cameras (a smaller baseline or focal length)");
  return g;
}

// Frame t of a recording at 30 frames/s.
StereoFrame MakeFrame(const cv::Mat& left, const cv::Mat& right, int t, int pattern_id) {
  StereoFrame frame;
  frame.left = left;
  frame.right = right;
  frame.index = t;
  frame.timestamp_left_ns = frame.timestamp_right_ns = static_cast<std::int64_t>(t) * 33'333'333;
  frame.pattern_id = pattern_id;
  return frame;
}

// Frame t: both images under pattern t.
StereoFrame ShadeFrame(const SynthGeometry& g, const SynthOptions& options, int t) {
  const int w = options.width, h = options.height, ss = options.supersample;
  const PatternImage pattern(options.pattern, t, options.frames, g.pattern_width, g.pattern_height, options.seed);
  const std::uint64_t noise_seed = options.seed * 0x100000001B3ULL + static_cast<std::uint64_t>(t) * 2 + 1;
  return MakeFrame(
      Shade(g.left, pattern, w, h, ss, options.ambient, options.optics_blur_px, options.image_noise_gray, noise_seed),
      Shade(g.right, pattern, w, h, ss, options.ambient, options.optics_blur_px, options.image_noise_gray,
            noise_seed + 1),
      t, pattern.pattern_id());
}

// A recording writer for FOLDER with the scene's meta.yaml.
std::unique_ptr<RecordingWriter> OpenWriter(const SynthRecording& recording, const SynthOptions& options,
                                            const std::string& folder, const SynthWriteOptions& write_options) {
  write_options.Check();
  RecordingMeta meta;
  meta["source"] = "rangebayes synth";
  meta["scene"] = ToString(options.scene);
  meta["pattern"] = ToString(options.pattern);
  meta["frames"] = std::to_string(options.frames);
  meta["image_noise_gray"] = std::to_string(options.image_noise_gray);
  meta["seed"] = std::to_string(options.seed);
  meta["baseline_m"] = std::to_string(options.baseline_m);
  meta["focal_px"] = std::to_string(recording.intrinsics.fx_px);
  meta["pixel_jitter_px"] = std::to_string(options.pixel_jitter_px);
  meta["pixel_jitter_cell_px"] = std::to_string(options.pixel_jitter_cell_px);
  RecordingWriterOptions writer_options;
  writer_options.overwrite = write_options.overwrite;
  writer_options.overwrite_flag = write_options.overwrite_flag;
  writer_options.png_compression = 9;
  return std::make_unique<RecordingWriter>(folder, recording.rig, meta, writer_options);
}

// FOLDER/ground_truth: depth and disparity of the left view (and the true points under pixel jitter).
void WriteGroundTruth(const SynthRecording& recording, const std::string& folder) {
  const std::filesystem::path gt = std::filesystem::path(folder) / "ground_truth";
  CreateFolder(gt.string());
  WritePfm(recording.depth_m, (gt / "depth_left_m.pfm").string());
  WritePfm(recording.disparity_px, (gt / "disparity_left_px.pfm").string());
  if (!recording.pixel_jitter_px.empty()) {
    // The true point of each left pixel's (jittered) ray: Z·((u + δu − cx)/f, (v + δv − cy)/f, 1).
    const CameraIntrinsics& k = recording.intrinsics;
    cv::Mat points(recording.depth_m.size(), CV_32FC3);
    for (int v = 0; v < points.rows; ++v)
      for (int u = 0; u < points.cols; ++u) {
        const float z = recording.depth_m.at<float>(v, u);
        const cv::Vec2f delta = recording.pixel_jitter_px.at<cv::Vec2f>(v, u);
        points.at<cv::Vec3f>(v, u) = cv::Vec3f(static_cast<float>((u + delta[0] - k.cx_px) / k.fx_px * z),
                                               static_cast<float>((v + delta[1] - k.cy_px) / k.fy_px * z), z);
      }
    WritePfm(points, (gt / "points_left_m.pfm").string());
  }
}

}  // namespace

std::string SynthRecording::BriefReport(const SynthOptions& options) const {
  double lo = 0, hi = 0;
  cv::minMaxLoc(disparity_px, &lo, &hi, nullptr, nullptr, disparity_px == disparity_px);  // NaN (no surface) left out
  char line[256];
  std::snprintf(line, sizeof(line), "%s under %s pattern, %d frames of %dx%d, disparity %.1f-%.1f px",
                ToString(options.scene).c_str(), ToString(options.pattern).c_str(),
                static_cast<int>(pattern_ids.size()), disparity_px.cols, disparity_px.rows, lo, hi);
  return line;
}

SynthRecording RenderSynthetic(const SynthOptions& options) {
  SynthGeometry g = BuildGeometry(options);
  for (int t = 0; t < options.frames; ++t) {
    StereoFrame frame = ShadeFrame(g, options, t);
    g.rec.left.push_back(frame.left);
    g.rec.right.push_back(frame.right);
    g.rec.pattern_ids.push_back(frame.pattern_id);
  }
  return std::move(g.rec);
}

void WriteSyntheticRecording(const SynthRecording& recording, const SynthOptions& options, const std::string& folder,
                             const SynthWriteOptions& write_options) {
  const std::unique_ptr<RecordingWriter> writer = OpenWriter(recording, options, folder, write_options);
  WriteGroundTruth(recording, folder);
  for (size_t t = 0; t < recording.left.size(); ++t) {
    writer->Write(MakeFrame(recording.left[t], recording.right[t], static_cast<int>(t), recording.pattern_ids[t]));
  }
  writer->Finish();
}

SynthRecording WriteSynthetic(const SynthOptions& options, const std::string& folder,
                              const SynthWriteOptions& write_options) {
  SynthGeometry g = BuildGeometry(options);
  const std::unique_ptr<RecordingWriter> writer = OpenWriter(g.rec, options, folder, write_options);
  WriteGroundTruth(g.rec, folder);  // it holds for every frame: a recording stopped early is whole as far as it goes
  for (int t = 0; t < options.frames; ++t) {
    if (write_options.stop && write_options.stop->load()) break;
    const StereoFrame frame = ShadeFrame(g, options, t);
    writer->Write(frame);
    g.rec.pattern_ids.push_back(frame.pattern_id);
    if (write_options.progress) write_options.progress(static_cast<double>(t + 1) / options.frames, "frames");
  }
  const int written = static_cast<int>(g.rec.pattern_ids.size());
  RecordingMeta extra;
  if (written < options.frames) {
    extra["frames"] = std::to_string(written);
    extra["stopped"] = StrCat("by request after ", written, " of ", options.frames, " frames");
  }
  writer->Finish(extra);
  return std::move(g.rec);
}

}  // namespace rangebayes
