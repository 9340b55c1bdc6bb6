#include <gtest/gtest.h>

#include "stereo_ground_dem/Se3.hpp"

using stereo_ground_dem::Se3;
using stereo_ground_dem::Vector6d;

TEST(Se3, ExpLogRoundTrip) {
  for (double scale : {1e-8, 1e-3, 0.3, 2.5}) {
    Vector6d xi;
    xi << 0.3, -1.2, 2.0, 0.4, -0.2, 0.7;
    xi *= scale;
    const Vector6d back = Se3::log(Se3::exp(xi));
    EXPECT_NEAR((back - xi).norm(), 0.0, 1e-10 * std::max(1.0, scale)) << scale;
  }
}

TEST(Se3, ExpMatchesFirstOrderAction) {
  Vector6d xi;
  xi << 1e-7, -2e-7, 3e-7, 2e-7, 1e-7, -1e-7;  // second-order terms ~1e-13
  const Eigen::Vector3d x(1.0, 2.0, 3.0);
  const Eigen::Vector3d expected = x + xi.head<3>() + xi.tail<3>().cross(x);
  EXPECT_NEAR((Se3::exp(xi) * x - expected).norm(), 0.0, 1e-12);
  EXPECT_NEAR((Se3::skew(xi.tail<3>()) * x - xi.tail<3>().cross(x)).norm(), 0.0, 1e-18);
}
