// PCL types stay in this adapter.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_plane.h>

#include "calibration/plane_target.h"
#include "core/error.h"

namespace rangebayes {

std::vector<int> RansacPlane(const Eigen::MatrixX3d& points, double threshold_m, int iterations,
                             Eigen::Vector4d* plane) {
  RB_CHECK(points.rows() >= 3, "plane fit: ", points.rows(), " points, need at least 3");
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(static_cast<size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    (*cloud)[static_cast<size_t>(i)] = pcl::PointXYZ(static_cast<float>(points(i, 0)), static_cast<float>(points(i, 1)),
                                                     static_cast<float>(points(i, 2)));
  }
  // random = false: PCL seeds its sampler with a fixed value, so the fit is repeatable.
  pcl::SampleConsensusModelPlane<pcl::PointXYZ>::Ptr model(
      new pcl::SampleConsensusModelPlane<pcl::PointXYZ>(cloud, false));
  pcl::RandomSampleConsensus<pcl::PointXYZ> ransac(model);
  ransac.setDistanceThreshold(threshold_m);
  ransac.setMaxIterations(iterations);
  RB_CHECK(ransac.computeModel(), "plane fit: RANSAC found no plane among ", points.rows(), " points");
  pcl::Indices inliers;
  ransac.getInliers(inliers);
  Eigen::VectorXf coefficients;
  ransac.getModelCoefficients(coefficients);
  RB_CHECK(coefficients.size() == 4, "plane fit: RANSAC returned no plane");
  *plane = coefficients.cast<double>();
  const double norm = plane->head<3>().norm();
  RB_CHECK(norm > 0, "plane fit: degenerate plane");
  *plane /= norm;
  return std::vector<int>(inliers.begin(), inliers.end());
}

}  // namespace rangebayes
