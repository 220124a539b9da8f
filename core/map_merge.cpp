#include "core/map_merge.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <random>

namespace rdslam {

Sim3 Sim3::inverse() const {
  Sim3 o;
  o.s = 1.0 / s;
  o.R = R.transpose();
  o.t = -(o.R * t) * o.s;
  return o;
}

Pose Sim3::camera(const Pose& T) const {
  // x_cam = R_c X + t_c with X = R^T (X' - t) / s; scaled by s: R_c R^T X' + s t_c - R_c R^T t.
  Pose out;
  out.R = T.R * R.transpose();
  out.t = s * T.t - out.R * t;
  return out;
}

bool umeyama_sim3(const std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>>& a,
                  const std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>>& b,
                  Sim3* S) {
  const int n = static_cast<int>(a.size());
  if (n < 3 || b.size() != a.size()) return false;
  Eigen::Matrix3Xd A(3, n), B(3, n);
  for (int i = 0; i < n; ++i) {
    A.col(i) = a[size_t(i)];
    B.col(i) = b[size_t(i)];
  }
  const Eigen::Matrix4d M = Eigen::umeyama(A, B, true);
  const Eigen::Matrix3d sR = M.topLeftCorner<3, 3>();
  const double s = sR.col(0).norm();
  if (!std::isfinite(s) || s < 1e-9) return false;
  S->s = s;
  S->R = sR / s;
  S->t = M.topRightCorner<3, 1>();
  return S->R.allFinite() && S->t.allFinite();
}

namespace {

// Both reprojections (S a into B, S^-1 b into A) within the chi-square gate.
bool is_inlier(const Sim3Pair& q, const Sim3& S, const Sim3& Si, const Pose& Ta, const Pose& Tb,
               const PinholeIntrinsics& K, double chi2) {
  const Eigen::Vector3d pb = Tb * (S * q.a);
  const Eigen::Vector3d pa = Ta * (Si * q.b);
  if (pb.z() <= 1e-9 || pa.z() <= 1e-9) return false;
  const double eb = (K.project(pb) - q.xb).squaredNorm() / (q.sb * q.sb);
  const double ea = (K.project(pa) - q.xa).squaredNorm() / (q.sa * q.sa);
  return eb < chi2 && ea < chi2;
}

int count_inliers(const std::vector<Sim3Pair, Eigen::aligned_allocator<Sim3Pair>>& pairs,
                  const Sim3& S, const Pose& Ta, const Pose& Tb, const PinholeIntrinsics& K,
                  double chi2, std::vector<uint8_t>* flags) {
  const Sim3 Si = S.inverse();
  int n = 0;
  for (size_t i = 0; i < pairs.size(); ++i) {
    const bool in = is_inlier(pairs[i], S, Si, Ta, Tb, K, chi2);
    if (flags) (*flags)[i] = in ? 1 : 0;
    n += in;
  }
  return n;
}

}  // namespace

int estimate_sim3(const std::vector<Sim3Pair, Eigen::aligned_allocator<Sim3Pair>>& pairs,
                  const Pose& Ta, const Pose& Tb, const PinholeIntrinsics& K,
                  const Sim3RansacParams& p, Sim3* S, std::vector<uint8_t>* inliers) {
  const int n = static_cast<int>(pairs.size());
  inliers->assign(pairs.size(), 0);
  if (n < std::max(3, p.min_inliers)) return 0;
  std::mt19937 rng(p.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> a(3), b(3);
  Sim3 best;
  int best_n = 0;
  for (int it = 0; it < p.iterations; ++it) {
    int i0 = pick(rng), i1 = pick(rng), i2 = pick(rng);
    if (i0 == i1 || i1 == i2 || i0 == i2) continue;
    a = {pairs[size_t(i0)].a, pairs[size_t(i1)].a, pairs[size_t(i2)].a};
    b = {pairs[size_t(i0)].b, pairs[size_t(i1)].b, pairs[size_t(i2)].b};
    Sim3 h;
    if (!umeyama_sim3(a, b, &h)) continue;
    const int k = count_inliers(pairs, h, Ta, Tb, K, p.chi2, nullptr);
    if (k > best_n) {
      best_n = k;
      best = h;
    }
  }
  if (best_n < p.min_inliers) return 0;
  // Refit on the inliers (twice: the refit may admit a few more).
  for (int pass = 0; pass < 2; ++pass) {
    count_inliers(pairs, best, Ta, Tb, K, p.chi2, inliers);
    a.clear();
    b.clear();
    for (int i = 0; i < n; ++i) {
      if (!(*inliers)[size_t(i)]) continue;
      a.push_back(pairs[size_t(i)].a);
      b.push_back(pairs[size_t(i)].b);
    }
    Sim3 h;
    if (!umeyama_sim3(a, b, &h)) break;
    if (count_inliers(pairs, h, Ta, Tb, K, p.chi2, nullptr) < static_cast<int>(a.size())) break;
    best = h;
  }
  const int k = count_inliers(pairs, best, Ta, Tb, K, p.chi2, inliers);
  if (k < p.min_inliers) return 0;
  *S = best;
  return k;
}

int merge_maps(Map& target, Map&& source, const Sim3& S,
               const std::vector<std::pair<int64_t, int64_t>>& fuse, int* kf_offset,
               int64_t* point_offset) {
  const int koff = target.next_kf_id;
  const int64_t poff = target.next_point_id;
  *kf_offset = koff;
  *point_offset = poff;
  for (auto& [id, k] : source.keyframes) {
    Keyframe& d = target.keyframes[id + koff];
    d = std::move(k);
    d.id = id + koff;
    d.T_cam_world = S.camera(d.T_cam_world);
    d.fixed = false;
    for (int64_t& pid : d.point_of) {
      if (pid >= 0) pid += poff;
    }
  }
  for (auto& [id, p] : source.points) {
    MapPoint& d = target.points[id + poff];
    d = std::move(p);
    d.id = id + poff;
    d.p_world = S * d.p_world;
    d.normal = S.R * d.normal;
    d.min_dist = static_cast<float>(d.min_dist * S.s);
    d.max_dist = static_cast<float>(d.max_dist * S.s);
    for (Observation& o : d.obs) o.kf += koff;
    if (d.first_kf >= 0) d.first_kf += koff;
    d.created_kf_seq += target.kf_seq;
  }
  target.next_kf_id += source.next_kf_id;
  target.next_point_id += source.next_point_id;
  target.kf_seq += source.kf_seq;
  int fused = 0;
  for (const auto& [src, dst] : fuse) {
    const int64_t from = src + poff;
    MapPoint* a = target.point(from);
    MapPoint* b = target.point(dst);
    if (a == nullptr || b == nullptr || from == dst) continue;
    const std::vector<Observation> obs = a->obs;
    target.erase_point(from);
    for (const Observation& o : obs) target.add_observation(dst, o.kf, o.feat);
    ++fused;
  }
  source = Map();
  return fused;
}

}  // namespace rdslam
