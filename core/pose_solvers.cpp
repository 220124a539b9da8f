#include "core/pose_solvers.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <vector>

namespace rdslam {

namespace {

bool finite3(const Eigen::Vector3d& v) {
  return std::isfinite(v.x() + v.y() + v.z());
}

// Adds the two DLT rows of one correspondence to the 12x12 normal matrix A^T A.
inline void accumulate_dlt(double xn, double yn, const Eigen::Vector4d& Xh,
                           Eigen::Matrix<double, 12, 12>* AtA) {
  Eigen::Matrix<double, 12, 1> r1, r2;
  r1 << Xh, Eigen::Vector4d::Zero(), -xn * Xh;
  r2 << Eigen::Vector4d::Zero(), Xh, -yn * Xh;
  AtA->selfadjointView<Eigen::Lower>().rankUpdate(r1);
  AtA->selfadjointView<Eigen::Lower>().rankUpdate(r2);
}

}  // namespace

bool solve_dlt(const Eigen::Vector2d* pixels, const Eigen::Vector3d* p_world, const int* idx,
               int count, const Intrinsics& K, const Eigen::Vector3d& centre, double scale,
               Mat34* P) {
  if (count < 6 || !(scale > 0.0)) return false;
  const double inv_s = 1.0 / scale;
  Eigen::Matrix<double, 12, 12> AtA = Eigen::Matrix<double, 12, 12>::Zero();
  for (int k = 0; k < count; ++k) {
    const int i = idx ? idx[k] : k;
    const double xn = (pixels[i].x() - K.cx) / K.fx;
    const double yn = (pixels[i].y() - K.cy) / K.fy;
    Eigen::Vector4d Xh;
    Xh << (p_world[i] - centre) * inv_s, 1.0;
    accumulate_dlt(xn, yn, Xh, &AtA);
  }
  if (!AtA.allFinite()) return false;
  Eigen::Matrix<double, 12, 1> p;
  if (count == 6) {
    // Minimal sample (the RANSAC inner loop): inverse iteration on A^T A. Its smallest
    // eigenvalue is ~0 and well separated for a non-degenerate sample, so a few solves with one
    // LDLT factorisation give the null vector at a fraction of an eigen-decomposition's cost.
    Eigen::Matrix<double, 12, 12> M = AtA.selfadjointView<Eigen::Lower>();
    const double tr = M.trace();
    M.diagonal().array() += 1e-12 * tr;  // keeps exact (noise-free) samples factorisable
    Eigen::LDLT<Eigen::Matrix<double, 12, 12>> ldlt(M);
    if (ldlt.info() != Eigen::Success) return false;
    // A second (near) zero pivot means the sample leaves P undetermined (e.g. coplanar).
    const auto D = ldlt.vectorD().cwiseAbs();
    const double dmax = D.maxCoeff();
    int tiny = 0;
    for (int k = 0; k < 12; ++k) tiny += D(k) <= 1e-9 * dmax;
    if (tiny >= 2 || !(dmax > 0.0)) return false;
    p.setConstant(1.0 / std::sqrt(12.0));
    for (int it = 0; it < 4; ++it) {
      p = ldlt.solve(p);
      const double nrm = p.norm();
      if (!(nrm > 0.0) || !std::isfinite(nrm)) return false;
      p /= nrm;
    }
  } else {
    // Non-minimal fit (all inliers): the null vector is the eigenvector of A^T A with the
    // smallest eigenvalue; a second eigenvalue as small means P is undetermined.
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> es(AtA);
    if (es.info() != Eigen::Success) return false;
    if (es.eigenvalues()(1) <= 1e-12 * es.eigenvalues()(11)) return false;
    p = es.eigenvectors().col(0);
  }
  Mat34 Pn;
  Pn.row(0) = p.segment<4>(0).transpose();
  Pn.row(1) = p.segment<4>(4).transpose();
  Pn.row(2) = p.segment<4>(8).transpose();
  // Undo the normalisations: x_pix = K x_n, X_norm = T X with T = [I/s, -c/s; 0 1].
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() *= inv_s;
  T.topRightCorner<3, 1>() = -centre * inv_s;
  Eigen::Matrix3d Km;
  Km << K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1;
  Mat34 out = Km * Pn * T;
  if (out.leftCols<3>().determinant() < 0) out = -out;
  if (!out.allFinite()) return false;
  *P = out;
  return true;
}

bool decompose_projection(const Mat34& P, const Intrinsics& K, Eigen::Matrix3d* R_cam_world,
                          Eigen::Vector3d* t_cam_world) {
  if (!P.allFinite()) return false;
  Mat34 M;  // K^-1 P, written out for an upper-triangular K without skew
  for (int c = 0; c < 4; ++c) {
    const double y = (P(1, c) - K.cy * P(2, c)) / K.fy;
    M(0, c) = (P(0, c) - K.cx * P(2, c)) / K.fx;
    M(1, c) = y;
    M(2, c) = P(2, c);
  }
  Eigen::Matrix3d A = M.leftCols<3>();
  double det = A.determinant();
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) return false;
  if (det < 0) {
    A = -A;
    M = -M;
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
  if (R.determinant() < 0) {  // cannot happen for det(A) > 0 up to round-off; be safe
    Eigen::Matrix3d U = svd.matrixU();
    U.col(2) = -U.col(2);
    R = U * svd.matrixV().transpose();
  }
  // Scale: the geometric mean of the singular values, cbrt(det A) (det A > 0 here).
  const double s = std::cbrt(std::abs(det));
  if (!(s > 0.0)) return false;
  *R_cam_world = R;
  *t_cam_world = M.col(3) / s;
  return R_cam_world->allFinite() && t_cam_world->allFinite();
}

Mat34 compose_projection(const Intrinsics& K, const Eigen::Matrix3d& R_cam_world,
                         const Eigen::Vector3d& t_cam_world) {
  Eigen::Matrix3d Km;
  Km << K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1;
  Mat34 Rt;
  Rt << R_cam_world, t_cam_world;
  return Km * Rt;
}

namespace {

// Largest real root of x^3 + a x^2 + b x + c.
double cubic_largest_root(double a, double b, double c) {
  const double q = (a * a - 3.0 * b) / 9.0;
  const double r = (2.0 * a * a * a - 9.0 * a * b + 27.0 * c) / 54.0;
  double x;
  if (r * r < q * q * q) {
    const double theta = std::acos(std::max(-1.0, std::min(1.0, r / std::sqrt(q * q * q))));
    x = -2.0 * std::sqrt(q) * std::cos(theta / 3.0) - a / 3.0;
    const double x2 = -2.0 * std::sqrt(q) * std::cos((theta + 2.0 * M_PI) / 3.0) - a / 3.0;
    const double x3 = -2.0 * std::sqrt(q) * std::cos((theta - 2.0 * M_PI) / 3.0) - a / 3.0;
    x = std::max(x, std::max(x2, x3));
  } else {
    double A = -std::cbrt(std::abs(r) + std::sqrt(r * r - q * q * q));
    if (r < 0) A = -A;
    const double B = (A == 0.0) ? 0.0 : q / A;
    x = A + B - a / 3.0;
  }
  // Newton polish: the trigonometric/Cardano forms lose digits near multiple roots.
  for (int it = 0; it < 3; ++it) {
    const double f = ((x + a) * x + b) * x + c;
    const double df = (3.0 * x + 2.0 * a) * x + b;
    if (df == 0.0) break;
    x -= f / df;
  }
  return x;
}

int solve_quadratic(double b, double c, double* r) {  // x^2 + b x + c
  double d = b * b - 4.0 * c;
  if (d < 0) {
    // Keep near-double roots that round-off pushed into the complex plane.
    if (d > -1e-10 * (b * b + std::abs(c) + 1e-30)) {
      d = 0;
    } else {
      return 0;
    }
  }
  const double s = std::sqrt(d);
  r[0] = 0.5 * (-b + s);
  r[1] = 0.5 * (-b - s);
  return 2;
}

}  // namespace

int solve_quartic(const double c[5], double roots[4]) {
  if (c[0] == 0.0 || !std::isfinite(c[0])) return 0;
  const double b = c[1] / c[0], cc = c[2] / c[0], d = c[3] / c[0], e = c[4] / c[0];
  // Depressed quartic y^4 + p y^2 + q y + r with x = y - b/4.
  const double b2 = b * b;
  const double p = cc - 3.0 * b2 / 8.0;
  const double q = d - b * cc / 2.0 + b2 * b / 8.0;
  const double r = e - b * d / 4.0 + b2 * cc / 16.0 - 3.0 * b2 * b2 / 256.0;
  double y[4];
  int ny = 0;
  if (std::abs(q) < 1e-14 * (1.0 + std::abs(p) + std::abs(r))) {
    double z[2];  // biquadratic
    const int nz = solve_quadratic(p, r, z);
    for (int i = 0; i < nz; ++i) {
      if (z[i] >= 0) {
        y[ny++] = std::sqrt(z[i]);
        y[ny++] = -std::sqrt(z[i]);
      }
    }
  } else {
    // Ferrari: (y^2 + p/2 + m)^2 = 2m y^2 - q y + m^2 + m p + p^2/4 - r is a perfect square
    // when 8m^3 + 8p m^2 + (2p^2 - 8r) m - q^2 = 0; its largest root is > 0.
    const double m = cubic_largest_root(p, (p * p - 4.0 * r) / 4.0, -q * q / 8.0);
    if (!(m > 0.0)) return 0;
    const double s = std::sqrt(2.0 * m);
    double z[2];
    int nz = solve_quadratic(-s, p / 2.0 + m + q / (2.0 * s), z);
    for (int i = 0; i < nz; ++i) y[ny++] = z[i];
    nz = solve_quadratic(s, p / 2.0 + m - q / (2.0 * s), z);
    for (int i = 0; i < nz; ++i) y[ny++] = z[i];
  }
  int n = 0;
  for (int i = 0; i < ny; ++i) {
    double x = y[i] - b / 4.0;
    for (int it = 0; it < 2; ++it) {  // Newton polish on the original polynomial
      const double f = (((x + b) * x + cc) * x + d) * x + e;
      const double df = ((4.0 * x + 3.0 * b) * x + 2.0 * cc) * x + d;
      if (df == 0.0) break;
      x -= f / df;
    }
    if (std::isfinite(x)) roots[n++] = x;
  }
  return n;
}

int solve_p3p(const Eigen::Vector3d f[3], const Eigen::Vector3d X[3], Eigen::Matrix3d R[4],
              Eigen::Vector3d t[4]) {
  // Grunert's solution (Haralick et al. 1994, Sec. 2.1): side lengths a, b, c opposite to
  // points 1, 2, 3; cosines of the angles between the bearings; distances s2 = u s1, s3 = v s1.
  const double a2 = (X[1] - X[2]).squaredNorm();
  const double b2 = (X[0] - X[2]).squaredNorm();
  const double c2 = (X[0] - X[1]).squaredNorm();
  if (!(b2 > 0.0) || !(a2 > 0.0) || !(c2 > 0.0)) return 0;
  const double ca = f[1].dot(f[2]), cb = f[0].dot(f[2]), cg = f[0].dot(f[1]);
  const double amc = (a2 - c2) / b2, apc = (a2 + c2) / b2;
  const double coef[5] = {
      (amc - 1.0) * (amc - 1.0) - 4.0 * c2 / b2 * ca * ca,
      4.0 * (amc * (1.0 - amc) * cb - (1.0 - apc) * ca * cg + 2.0 * c2 / b2 * ca * ca * cb),
      2.0 * (amc * amc - 1.0 + 2.0 * amc * amc * cb * cb + 2.0 * (b2 - c2) / b2 * ca * ca -
             4.0 * apc * ca * cb * cg + 2.0 * (b2 - a2) / b2 * cg * cg),
      4.0 * (-amc * (1.0 + amc) * cb + 2.0 * a2 / b2 * cg * cg * cb - (1.0 - apc) * ca * cg),
      (1.0 + amc) * (1.0 + amc) - 4.0 * a2 / b2 * cg * cg};
  double vs[4];
  const int nv = solve_quartic(coef, vs);
  // World triangle frame (shared by all solutions).
  const Eigen::Vector3d dx1 = X[1] - X[0], dx2 = X[2] - X[0];
  const Eigen::Vector3d nx = dx1.cross(dx2);
  if (!(nx.squaredNorm() > 1e-24 * dx1.squaredNorm() * dx2.squaredNorm())) return 0;  // collinear
  Eigen::Matrix3d Ex;
  Ex.col(0) = dx1.normalized();
  Ex.col(2) = nx.normalized();
  Ex.col(1) = Ex.col(2).cross(Ex.col(0));
  int ns = 0;
  for (int k = 0; k < nv; ++k) {
    const double v = vs[k];
    if (!(v > 0.0)) continue;
    const double den = 2.0 * (cg - v * ca);
    if (std::abs(den) < 1e-12) continue;
    const double u = ((-1.0 + amc) * v * v - 2.0 * amc * cb * v + 1.0 + amc) / den;
    if (!(u > 0.0)) continue;
    const double s1sq = b2 / (1.0 + v * v - 2.0 * v * cb);
    if (!(s1sq > 0.0)) continue;
    const double s1 = std::sqrt(s1sq);
    const Eigen::Vector3d Y0 = s1 * f[0], Y1 = u * s1 * f[1], Y2 = v * s1 * f[2];
    // Rigid transform taking the world triangle onto the camera-frame triangle.
    const Eigen::Vector3d dy1 = Y1 - Y0, dy2 = Y2 - Y0;
    const Eigen::Vector3d ny = dy1.cross(dy2);
    if (!(ny.squaredNorm() > 0.0)) continue;
    Eigen::Matrix3d Ey;
    Ey.col(0) = dy1.normalized();
    Ey.col(2) = ny.normalized();
    Ey.col(1) = Ey.col(2).cross(Ey.col(0));
    const Eigen::Matrix3d Rk = Ey * Ex.transpose();
    const Eigen::Vector3d tk = Y0 - Rk * X[0];
    if (!Rk.allFinite() || !finite3(tk)) continue;
    R[ns] = Rk;
    t[ns] = tk;
    if (++ns == 4) break;
  }
  return ns;
}

bool opencv_magsac_pnp(const Eigen::Vector2d* pixels, const Eigen::Vector3d* p_world, int count,
                       const Intrinsics& K, int max_iterations, double threshold_px,
                       double confidence, int seed, Eigen::Matrix3d* R_cam_world,
                       Eigen::Vector3d* t_cam_world, uint8_t* inlier_mask) {
  if (count < 4) return false;
  std::vector<cv::Point3d> obj(count);
  std::vector<cv::Point2d> img(count);
  for (int i = 0; i < count; ++i) {
    obj[i] = cv::Point3d(p_world[i].x(), p_world[i].y(), p_world[i].z());
    img[i] = cv::Point2d(pixels[i].x(), pixels[i].y());
  }
  cv::Mat Kc = (cv::Mat_<double>(3, 3) << K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1);
  cv::UsacParams up;
  up.sampler = cv::SAMPLING_UNIFORM;
  up.score = cv::SCORE_METHOD_MAGSAC;
  up.loMethod = cv::LOCAL_OPTIM_SIGMA;
  up.maxIterations = max_iterations;
  up.threshold = threshold_px;
  up.confidence = confidence;
  up.randomGeneratorState = seed;
  up.isParallel = false;
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  bool ok = false;
  try {
    ok = cv::solvePnPRansac(obj, img, Kc, cv::noArray(), rvec, tvec, inliers, up);
  } catch (const cv::Exception&) {
    ok = false;  // OpenCV throws on degenerate input; a reference run reports "no model"
  }
  if (!ok || rvec.empty() || tvec.empty()) return false;
  cv::Mat Rm;
  cv::Rodrigues(rvec, Rm);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) (*R_cam_world)(r, c) = Rm.at<double>(r, c);
    (*t_cam_world)(r) = tvec.at<double>(r);
  }
  if (inlier_mask) {
    for (int i = 0; i < count; ++i) inlier_mask[i] = 0;
    for (int i : inliers) {
      if (i >= 0 && i < count) inlier_mask[i] = 1;
    }
  }
  return true;
}

}  // namespace rdslam
