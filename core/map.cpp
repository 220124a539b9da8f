#include "core/map.h"

#include <algorithm>
#include <cmath>

namespace rdslam {

MapPoint* Map::point(int64_t id) {
  auto it = points.find(id);
  return it == points.end() ? nullptr : &it->second;
}

Keyframe* Map::keyframe(int id) {
  auto it = keyframes.find(id);
  return it == keyframes.end() ? nullptr : &it->second;
}

bool Map::add_observation(int64_t pid, int kf, int feat) {
  MapPoint* p = point(pid);
  Keyframe* k = keyframe(kf);
  if (!p || !k || feat < 0 || feat >= static_cast<int>(k->point_of.size())) return false;
  if (k->point_of[feat] >= 0) return false;
  for (const auto& o : p->obs) {
    if (o.kf == kf) return false;  // one observation per keyframe
  }
  k->point_of[feat] = pid;
  p->obs.push_back({kf, feat});
  return true;
}

void Map::remove_observation(int64_t pid, int kf) {
  MapPoint* p = point(pid);
  if (!p) return;
  for (size_t i = 0; i < p->obs.size(); ++i) {
    if (p->obs[i].kf != kf) continue;
    Keyframe* k = keyframe(kf);
    if (k && p->obs[i].feat < static_cast<int>(k->point_of.size()) &&
        k->point_of[p->obs[i].feat] == pid) {
      k->point_of[p->obs[i].feat] = -1;
    }
    p->obs.erase(p->obs.begin() + static_cast<long>(i));
    return;
  }
}

void Map::erase_point(int64_t pid) {
  MapPoint* p = point(pid);
  if (!p) return;
  for (const auto& o : p->obs) {
    Keyframe* k = keyframe(o.kf);
    if (k && o.feat < static_cast<int>(k->point_of.size()) && k->point_of[o.feat] == pid) {
      k->point_of[o.feat] = -1;
    }
  }
  points.erase(pid);
}

void Map::erase_keyframe(int kf) {
  Keyframe* k = keyframe(kf);
  if (!k) return;
  for (int64_t pid : k->point_of) {
    if (pid < 0) continue;
    MapPoint* p = point(pid);
    if (!p) continue;
    for (size_t i = 0; i < p->obs.size(); ++i) {
      if (p->obs[i].kf == kf) {
        p->obs.erase(p->obs.begin() + static_cast<long>(i));
        break;
      }
    }
    if (p->first_kf == kf && !p->obs.empty()) p->first_kf = p->obs.front().kf;
  }
  keyframes.erase(kf);
}

std::vector<std::pair<int, int>> Map::covisible(int kf, int min_shared) const {
  std::vector<std::pair<int, int>> out;
  auto it = keyframes.find(kf);
  if (it == keyframes.end()) return out;
  std::unordered_map<int, int> count;
  for (int64_t pid : it->second.point_of) {
    if (pid < 0) continue;
    auto pit = points.find(pid);
    if (pit == points.end()) continue;
    for (const auto& o : pit->second.obs) {
      if (o.kf != kf) ++count[o.kf];
    }
  }
  for (const auto& [id, c] : count) {
    if (c >= min_shared) out.emplace_back(c, id);
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second > b.second;
  });
  return out;
}

void Map::update_point_geometry(MapPoint& p, float scale_factor, int levels) const {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  int cnt = 0;
  for (const auto& o : p.obs) {
    auto it = keyframes.find(o.kf);
    if (it == keyframes.end()) continue;
    const Eigen::Vector3d v = it->second.T_cam_world.centre() - p.p_world;
    const double d = v.norm();
    if (d > 1e-12) n += v / d;
    ++cnt;
  }
  if (cnt > 0 && n.norm() > 1e-12) p.normal = n.normalized();
  // Distance range from the reference (first) observation's pyramid level, as in ORB-SLAM.
  auto it = keyframes.find(p.first_kf);
  if (it == keyframes.end() && !p.obs.empty()) it = keyframes.find(p.obs.front().kf);
  if (it == keyframes.end()) return;
  int feat = -1;
  for (const auto& o : p.obs) {
    if (o.kf == it->first) feat = o.feat;
  }
  if (feat < 0) return;
  const float dist = static_cast<float>((p.p_world - it->second.T_cam_world.centre()).norm());
  const float lvl_scale = it->second.features.scale[feat];
  p.max_dist = dist * lvl_scale * 1.2f;
  p.min_dist =
      p.max_dist / std::pow(scale_factor, static_cast<float>(std::max(1, levels - 1))) / 1.44f;
}

Map::Redundancy Map::redundancy(const Keyframe& kf) const {
  Redundancy r;
  for (int64_t pid : kf.point_of) {
    if (pid < 0) continue;
    const auto it = points.find(pid);
    if (it == points.end()) continue;
    ++r.total;
    if (!it->second.valid || it->second.obs.size() >= 4) ++r.redundant;
  }
  return r;
}

int Map::count_valid_points() const {
  int n = 0;
  for (const auto& kv : points) n += kv.second.valid ? 1 : 0;
  return n;
}

}  // namespace rdslam
