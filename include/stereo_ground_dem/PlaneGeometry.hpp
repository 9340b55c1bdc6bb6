#pragma once
/// \file PlaneGeometry.hpp
/// Formulas of METHOD.md sections 2 and 4 for one triangle of the ground mesh seen from a camera.
///
/// The camera pose is `camera_T_ground` (X_c = R X_g + t). A triangle with ground vertices
/// (x_i, y_i, z_i) lies on the plane z = p x + q y + c, which in the camera frame is m^T X_c = 1 with
///     m = R n_g / (c + n_g^T R^T t),   n_g = (-p, -q, 1).
/// For a pixel u with normalised ray xhat = K^{-1} (u, 1), the plane's inverse depth is m^T xhat.
/// A second camera with X_j = R_j X_c + t_j sees the plane through H_j(m) = K R_j (I + t' m^T) K^{-1},
/// t' = R_j^T t_j. The inverse compositional increment acting on the reference image is
/// G(delta) = K (I + t' delta^T) K^{-1}, and H_j(m) G(delta)^{-1} = H_j(m') with
///     m' = m - (1 + m^T t') delta / (1 + delta^T t').

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

namespace stereo_ground_dem {

class PlaneGeometry {
 public:
  using Matrix36d = Eigen::Matrix<double, 3, 6>;

  /// Plane (p, q, c) through three ground points; its 3x3 map from the heights: (p,q,c) = Minv z.
  static Eigen::Matrix3d heightsToPlane(const std::array<Eigen::Vector2d, 3>& xy);

  /// m of the plane (p, q, c) seen from camera_T_ground. Returns false if the camera lies on the
  /// plane (m undefined).
  static bool cameraPlane(const Eigen::Isometry3d& camera_T_ground, const Eigen::Vector3d& pqc,
                          Eigen::Vector3d* m);

  /// d m / d (p, q, c) at the plane (p, q, c).
  static Eigen::Matrix3d cameraPlaneJacobian(const Eigen::Isometry3d& camera_T_ground,
                                             const Eigen::Vector3d& pqc);

  /// d m / d xi of the plane as seen from exp(xi) * camera_T_ground, xi = (v, omega):
  /// [-m m^T, -[m]_x].
  static Matrix36d cameraPlaneMotionJacobian(const Eigen::Vector3d& m);

  /// The homography K R_j (I + t' m^T) K^{-1} mapping reference pixels to pixels of camera j.
  static Eigen::Matrix3d homography(const Eigen::Matrix3d& k, const Eigen::Isometry3d& target_T_reference,
                                    const Eigen::Vector3d& m);

  /// The plane increment of the inverse compositional step that corresponds to a change dm of
  /// the plane: first-order inverse of m' = m - (1 + m^T t') delta, i.e. delta = -dm / (1 + m^T t').
  static double deltaScale(const Eigen::Vector3d& m, const Eigen::Vector3d& t_prime) {
    return -1.0 / (1.0 + m.dot(t_prime));
  }

  /// d G(u; delta) / d delta at delta = 0: how the reference pixel moves under the plane increment,
  /// (d pi at xhat) t' xhat^T (2x3), with d pi = [fx 0 -fx x; 0 fy -fy y] for xhat = (x, y, 1).
  /// The photometric Jacobian row of a pixel is grad I0 times this; the estimator evaluates it as
  /// (c . t') xhat^T with c = (d pi)^T grad I0, a per-pixel constant of the reference image.
  static Eigen::Matrix<double, 2, 3> planeIncrementDisplacement(const Eigen::Matrix3d& k,
                                                                const Eigen::Vector3d& xhat,
                                                                const Eigen::Vector3d& t_prime);

  /// How the reference pixel of a fixed ground point moves when the reference pose becomes
  /// exp(xi) * camera_T_ground (2x6): (d pi at X) [I, -[X]_x] with X = xhat / rho the point on the
  /// surface, i.e. rho (d pi at xhat) for translation and -(d pi at xhat) [xhat]_x for rotation.
  static Eigen::Matrix<double, 2, 6> worldMotionDisplacement(const Eigen::Matrix3d& k,
                                                             const Eigen::Vector3d& xhat, double rho);

  /// m' of the composition H_j(m) G(delta)^{-1} (exact).
  static Eigen::Vector3d composeInverse(const Eigen::Vector3d& m, const Eigen::Vector3d& delta,
                                        const Eigen::Vector3d& t_prime) {
    return m - (1.0 + m.dot(t_prime)) / (1.0 + delta.dot(t_prime)) * delta;
  }
};

}  // namespace stereo_ground_dem
