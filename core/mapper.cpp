#include "core/mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <set>
#include <unordered_set>

#include "core/log.h"
#include "core/matching.h"
#include "core/prefix_visitor.h"

namespace rdslam {

void MapperParams::visit(ParamVisitor& v) {
  v.field("m2", m2, 0, 100000, "paper Sec. 4: new points a keyframe must contribute (50-100)");
  v.field("m2_weak_tracking", m2_weak_tracking,
          "a candidate that tracked fewer points than m2 needs more new points than it tracked");
  v.field("related_keyframes", related_keyframes, 1, 50,
          "paper Sec. 4: keyframes matched for triangulation");
  v.field("max_keyframes", max_keyframes, 3, 100000, "cap on keyframes (oldest culled)");
  v.field("max_points", max_points, 100, 10000000, "cap on map points");
  v.field("min_parallax_deg", min_parallax_deg, 0.0, 45.0, "triangulation angle of new points");
  v.field("redundant_fraction", redundant_fraction, 0.0, 1.0,
          "Sec. 4's 90% rule: invalid or shared points above this fraction cull the keyframe "
          "(mapper) or mark it invalid (map updating)");
  v.field("max_epochs", max_epochs, 0, 16,
          "recovery: earlier maps kept frozen for relocalization and merging (0: none)");
  v.field("merge_min_inliers", merge_min_inliers, 6, 10000,
          "recovery: Sim(3) RANSAC inliers a merge with an earlier map needs");
  v.field("merge_min_matches", merge_min_matches, 6, 10000,
          "recovery: keyframe features matched by projection a merge needs");
  v.field("ba_young_keyframes", ba_young_keyframes, 0, 100000,
          "a map with fewer keyframes is young for the local BA window (0: never)");
  v.field("ba_young_window", ba_young_window, 2, 1000,
          "young map: keyframes in the local BA window (at most ba.window)");
  v.field("ba_young_span_frames", ba_young_span_frames, 0, 100000,
          "young map: the window grows (up to ba.window) while it spans fewer tracker frames");
  v.field("ba_yield", ba_yield,
          "live pipeline: local BA stops (or is skipped) when another keyframe candidate waits, "
          "so new keyframes are mapped first (ORB-SLAM's abort flag); no effect on lossless "
          "replay, where the tracker waits for the mapper");
  PrefixVisitor ba_v(v, "ba_");
  ba.visit(ba_v);
}

Mapper::Mapper(const MapperParams& params, const FeatureParams& features, const CameraModel& camera,
               std::shared_ptr<SlamLink> link)
    : params_(params),
      fparams_(features),
      K_{camera.fx, camera.fy, camera.cx, camera.cy},
      camera_(camera),
      link_(std::move(link)) {
  cand_.resize(2048);
  if (link_->vocabulary && fparams_.binary()) {
    places_ = std::make_unique<KeyframeDatabaseBuilder>(link_->vocabulary->words());
  }
}

void Mapper::add_place(int kf) {
  // Place recognition: the keyframe's bag-of-words vector enters the database (published with
  // the next snapshot; removed keyframes leave it at publish()).
  const Keyframe* k = map_.keyframe(kf);
  if (!places_ || k == nullptr) return;
  link_->vocabulary->transform(k->features, bow_, voc_scratch_);
  places_->add(epoch_, kf, bow_);
}

void Mapper::set_change_detection(const ChangeDetectionParams& p) {
  updater_ = p.needs_updater()
                 ? std::make_unique<MapUpdater>(p, camera_, params_.redundant_fraction)
                 : nullptr;
}

void Mapper::load(Map&& map) {
  map_ = std::move(map);
  epoch_ = 0;
  trail_.clear();
  if (updater_) updater_->reset();
  if (places_) {
    places_->clear();
    for (const auto& kv : map_.keyframes) add_place(kv.first);
  }
  publish();
}

bool Mapper::save(const std::string& path, int keep, std::string* error, MapInfo* info,
                  double* ms) {
  return save_map_file(map_, camera_, fparams_, path, keep, error, info, ms);
}

bool run_map_save_job(const MapSaveJob& job) {
  std::string err;
  MapInfo info;
  double ms = 0.0;
  timespec c0{}, c1{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c0);
  const bool ok = save_map_file(job.map, job.camera, job.features, job.path, job.keep, &err, &info,
                                &ms, job.saved_unix_s);
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c1);
  const double cpu_ms = (c1.tv_sec - c0.tv_sec) * 1e3 + (c1.tv_nsec - c0.tv_nsec) * 1e-6;
  if (ok) {
    if (job.link) job.link->saves_done.fetch_add(1, std::memory_order_relaxed);
    RDSLAM_LOG_INFO(
        "mapper: map saved to %s (%d keyframes, %d points, %.1f MiB; copy %.1f ms on the mapper "
        "thread, encode and write %.0f ms (%.0f ms CPU) on the map writer thread)",
        job.path.c_str(), info.keyframes, info.points, info.file_bytes / 1048576.0, job.copy_ms, ms,
        cpu_ms);
    return true;
  }
  if (job.link) job.link->saves_failed.fetch_add(1, std::memory_order_relaxed);
  RDSLAM_LOG_ERROR("mapper: map not saved: %s", err.c_str());
  return false;
}

void Mapper::serve_save_requests() {
  // A save request (SlamLink::save_requests) is served between two units of work, on this
  // thread, which owns the map; the tracker keeps tracking on the last published snapshot.
  const uint32_t want = link_->save_requests.load(std::memory_order_acquire);
  if (want == saves_served_) return;
  const bool handoff = save_writer_ != nullptr && !save_path_.empty();
  if (handoff && save_writer_->busy()) return;  // served by the next copy (coalesced)
  if (want - saves_served_ > 1) {
    link_->saves_coalesced.fetch_add(want - saves_served_ - 1, std::memory_order_relaxed);
  }
  saves_served_ = want;
  if (handoff) {
    const auto t0 = std::chrono::steady_clock::now();
    auto job = std::make_unique<MapSaveJob>();
    job->map = copy_map_for_save(map_);
    job->camera = camera_;
    job->features = fparams_;
    job->path = save_path_;
    job->keep = save_keep_;
    job->saved_unix_s = static_cast<int64_t>(std::time(nullptr));
    job->link = link_;
    job->copy_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    save_writer_->submit(std::move(job));
    return;
  }
  std::string err = save_path_.empty() ? "no map file configured" : "";
  MapInfo info;
  double ms = 0.0;
  if (!save_path_.empty() && save(save_path_, save_keep_, &err, &info, &ms)) {
    link_->saves_done.fetch_add(1, std::memory_order_relaxed);
    RDSLAM_LOG_INFO("mapper: map saved to %s (%d keyframes, %d points, %.1f MiB, %.0f ms)",
                    save_path_.c_str(), info.keyframes, info.points, info.file_bytes / 1048576.0,
                    ms);
  } else {
    link_->saves_failed.fetch_add(1, std::memory_order_relaxed);
    RDSLAM_LOG_ERROR("mapper: map not saved: %s", err.c_str());
  }
}

bool Mapper::step(int timeout_ms) {
  serve_save_requests();
  KeyframeCandidate* c = link_->candidates.front();
  FrameObservation* o = c ? nullptr : link_->observations.front();
  if (!c && !o) {
    const uint32_t ticket = link_->bell.ticket();
    c = link_->candidates.front();
    o = c ? nullptr : link_->observations.front();
    if (!c && !o && timeout_ms > 0) {
      link_->bell.wait(ticket, timeout_ms);
      c = link_->candidates.front();
      o = c ? nullptr : link_->observations.front();
    }
    if (!c && !o) {
      link_->index.collect();
      return false;
    }
  }
  link_->mapper_busy.store(1, std::memory_order_relaxed);
  if (c) {
    process(*c);
    link_->candidates.pop();
  } else {
    process_observation(*o);
    link_->observations.pop();
  }
  link_->mapper_busy.store(0, std::memory_order_release);
  link_->mapped.ring();
  return true;
}

void Mapper::account(const MapUpdateStats& u) {
  stats_.points_invalidated += u.points_invalidated;
  stats_.keyframes_invalidated += u.keyframes_invalidated;
  stats_.points_counter_discarded += u.counter_discards;
  stats_.points_pruned += u.points_pruned;
  stats_.points_culled += u.points_pruned;
  link_->invalidated_points.fetch_add(u.points_invalidated, std::memory_order_relaxed);
}

int Mapper::remove_invalid_keyframes() {
  // Sec. 4: an invalid keyframe no longer describes the scene; removing it lets the tracker's
  // keyframe rule (fewer points shared with the reference) select a new frame in its place.
  // Its observations go with it; points left with fewer than 2 views go at the next cull.
  std::vector<int> bad;
  for (const auto& [id, k] : map_.keyframes) {
    if (!k.valid && !k.fixed) bad.push_back(id);
  }
  for (int id : bad) {
    if (map_.keyframes.size() <= 2) break;  // keep a map to track against
    retire_keyframe(id);
    ++stats_.keyframes_replaced;
    ++stats_.keyframes_culled;
  }
  return static_cast<int>(bad.size());
}

void Mapper::process_observation(const FrameObservation& o) {
  if (link_->localize_only.load(std::memory_order_relaxed)) return;  // the map is frozen
  if (!updater_ || o.epoch != epoch_ || map_.keyframes.empty()) return;
  UpdateFrame f;
  f.image = &o.image;
  f.T_cam_world = o.T_cam_world;
  f.un = o.un.data();
  f.point_of = o.point_of.data();
  f.count = o.tracked;
  f.rejected = o.rejected_ids.data();
  f.rejected_count = o.rejected;
  f.frame_no = o.frame_no;
  f.stamp_ns = o.stamp_ns;
  const auto t0 = std::chrono::steady_clock::now();
  const MapUpdateStats u = updater_->update(map_, f, nullptr, inval_log_);
  stats_.update_ms_total +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  ++stats_.observations;
  account(u);
  if (u.keyframes_invalidated > 0) remove_invalid_keyframes();
  // Invalid points leave the tracker's matching index now, not at the next keyframe.
  if (u.map_changed()) publish();
}

void Mapper::process(const KeyframeCandidate& c) {
  switch (c.kind) {
    case KeyframeCandidate::Kind::kReset:
      start_epoch(c.epoch);
      return;
    case KeyframeCandidate::Kind::kInit:
      handle_init(c);
      return;
    case KeyframeCandidate::Kind::kKeyframe:
      if (link_->localize_only.load(std::memory_order_relaxed)) return;  // the map is frozen
      // The tracker relocalized into a kept earlier map: it becomes the current map again.
      if (c.epoch != epoch_ && !reactivate(c.epoch)) return;
      if (c.epoch == epoch_ && !map_.keyframes.empty()) {
        const bool changed = update_on_candidate(c);
        const int published = stats_.snapshots;
        handle_keyframe(c);
        // A rejected candidate does not publish: invalid points still leave the index now.
        if (changed && stats_.snapshots == published) publish();
      }
      return;
  }
}

bool Mapper::update_on_candidate(const KeyframeCandidate& c) {
  // Sec. 4 map updating on the candidate, before it is inserted: Algorithm 1 with the candidate
  // as the current frame (core/map_updater.h); invalid keyframes go now. True if the map
  // changed.
  if (!updater_) return false;
  UpdateFrame f;
  f.image = &c.image;
  f.T_cam_world = c.T_cam_world;
  f.un = c.features.un.data();
  f.point_of = c.point_of.data();
  f.count = std::min<int>(c.features.count, static_cast<int>(c.point_of.size()));
  f.stamp_ns = c.stamp_ns;
  const MapUpdateStats u = updater_->update(map_, f, nullptr, inval_log_);
  account(u);
  if (u.keyframes_invalidated > 0) remove_invalid_keyframes();
  return u.map_changed();
}

void Mapper::handle_init(const KeyframeCandidate& c) {
  if (places_) places_->retain(c.epoch, [](int) { return false; });
  map_ = Map();
  trail_.clear();
  epoch_ = c.epoch;
  // The tracker's pyramid for this map (TrackerParams::fast_motion_levels after fast motion).
  if (c.levels > 0) fparams_.levels = c.levels;
  ++stats_.maps_started;
  Keyframe& k0 = map_.keyframes[0];
  k0.id = 0;
  k0.fixed = true;
  k0.stamp_ns = c.stamp0_ns;
  k0.frame_no = c.frame_no0;
  k0.features.copy_from(c.features0);
  k0.point_of.assign(c.features0.count, -1);
  c.image0.copyTo(k0.image);
  Keyframe& k1 = map_.keyframes[1];
  k1.id = 1;
  k1.stamp_ns = c.stamp_ns;
  k1.frame_no = c.frame_no;
  k1.T_cam_world = c.T_cam_world;
  k1.features.copy_from(c.features);
  k1.point_of.assign(c.features.count, -1);
  c.image.copyTo(k1.image);
  const size_t bytes = static_cast<size_t>(c.features.desc.cols) * c.features.desc.elemSize();
  for (size_t k = 0; k < c.init_points.size(); ++k) {
    const InitPoint& ip = c.init_points[k];
    MapPoint p;
    p.id = static_cast<int64_t>(k);
    p.p_world = ip.p_world;
    p.first_kf = 0;
    p.created_kf_seq = 0;
    const uint8_t* d = c.features.desc_ptr(ip.feat1);
    p.desc.assign(d, d + bytes);
    map_.points.emplace(p.id, std::move(p));
    map_.add_observation(static_cast<int64_t>(k), 0, ip.feat0);
    map_.add_observation(static_cast<int64_t>(k), 1, ip.feat1);
  }
  map_.next_point_id = static_cast<int64_t>(c.init_points.size());
  map_.next_kf_id = 2;
  map_.kf_seq = 2;
  for (auto& kv : map_.points) {
    map_.update_point_geometry(kv.second, float(fparams_.scale_factor), fparams_.levels);
  }
  stats_.keyframes_accepted += 2;
  if (places_) {
    add_place(0);  // kept earlier maps keep their places (recovery)
    add_place(1);
  }
  publish();
}

std::vector<int> Mapper::related_keyframes(int kf) const {
  std::vector<int> out;
  for (const auto& [n, id] : map_.covisible(kf)) {
    if (static_cast<int>(out.size()) >= params_.related_keyframes) break;
    out.push_back(id);
  }
  // Too few covisible keyframes (e.g. just after relocalization): add the most recent ones.
  for (auto it = map_.keyframes.rbegin();
       it != map_.keyframes.rend() && static_cast<int>(out.size()) < params_.related_keyframes;
       ++it) {
    if (it->first == kf || std::find(out.begin(), out.end(), it->first) != out.end()) continue;
    out.push_back(it->first);
  }
  return out;
}

int Mapper::triangulate(int kf_id, const std::vector<int>& related, const cv::Mat& image,
                        std::vector<int64_t>& created) {
  // Sec. 4 "track triangulation": the candidate's features without a map point are matched
  // against each related keyframe in turn; a feature that got a point is not matched again.
  const Keyframe& C = *map_.keyframe(kf_id);
  const Features& fc = C.features;
  std::vector<char> used(fc.count, 0);
  for (int j = 0; j < fc.count; ++j) used[j] = C.point_of[j] >= 0;
  int n_new = 0;
  for (int rid : related) {
    const Keyframe* R = triangulation_partner(C, rid);
    if (!R) continue;
    match_epipolar(C, *R, used);
    for (int j = 0; j < fc.count; ++j) {
      const int i = claims_.target_of(j);
      if (i < 0 || used[j] || R->point_of[i] >= 0) continue;
      Eigen::Vector3d p;
      if (!triangulate_match(C, *R, j, i, image, p)) continue;
      created.push_back(create_point(kf_id, rid, j, i, p));
      used[j] = 1;
      ++n_new;
    }
  }
  return n_new;
}

Keyframe* Mapper::triangulation_partner(const Keyframe& C, int rid) {
  // Pair selection: a related keyframe (still in the map) whose baseline to the candidate is
  // not tiny compared with its median scene depth (ORB-SLAM's test).
  Keyframe* R = map_.keyframe(rid);
  if (!R) return nullptr;
  std::vector<double> depth;
  for (int i = 0; i < R->features.count; ++i) {
    if (R->point_of[i] < 0) continue;
    const MapPoint* p = map_.point(R->point_of[i]);
    if (p) depth.push_back((R->T_cam_world * p->p_world).z());
  }
  if (depth.empty()) return nullptr;
  std::nth_element(depth.begin(), depth.begin() + depth.size() / 2, depth.end());
  const double baseline = (C.T_cam_world.centre() - R->T_cam_world.centre()).norm();
  if (baseline / std::max(1e-9, depth[depth.size() / 2]) < 0.01) return nullptr;
  return R;
}

void Mapper::match_epipolar(const Keyframe& C, const Keyframe& R, const std::vector<char>& used) {
  // Epipolar matching: each free feature j of the candidate C against R's free features near
  // its epipolar line (MatchPurpose::kTriangulate); one-to-one by best distance (claims_).
  const Features& fc = C.features;
  const Features& fr = R.features;
  const bool bin = fparams_.binary();
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kTriangulate, bin);
  const Eigen::Matrix3d F = fundamental_from_poses(K_, R.T_cam_world, C.T_cam_world);
  // Epipole in C (projection of R's centre): matches near it have no parallax.
  const Eigen::Vector3d ec = C.T_cam_world * R.T_cam_world.centre();
  const bool has_epi = ec.z() > 1e-9;
  const Eigen::Vector2d epi = has_epi ? K_.project(ec) : Eigen::Vector2d(-1e9, -1e9);
  // R's free features, bucketed by the epipolar lines through R's epipole (the projection of
  // C's centre) that pass within their band (core/epipolar_bins.h): the same matches as a scan
  // of all of them, at a fraction of the cost.
  r_free_.clear();
  r_x_.clear();
  r_y_.clear();
  r_band_.clear();
  for (int i = 0; i < fr.count; ++i) {
    if (R.point_of[i] >= 0) continue;
    r_free_.push_back(i);
    r_x_.push_back(fr.un[i].x);
    r_y_.push_back(fr.un[i].y);
    r_band_.push_back(std::sqrt(3.84) * fr.scale[i]);
  }
  const Eigen::Vector3d cr = R.T_cam_world * C.T_cam_world.centre();
  const Eigen::Vector3d er(K_.fx * cr.x() + K_.cx * cr.z(), K_.fy * cr.y() + K_.cy * cr.z(),
                           cr.z());
  epi_bins_.build(er, r_free_.data(), r_x_.data(), r_y_.data(), r_band_.data(),
                  static_cast<int>(r_free_.size()));
  claims_.reset(fc.count, fr.count);
  for (int j = 0; j < fc.count; ++j) {
    if (used[j]) continue;
    const Eigen::Vector2d xj(fc.un[j].x, fc.un[j].y);
    if ((xj - epi).squaredNorm() < 100.0 * fc.scale[j] * fc.scale[j]) continue;
    // Epipolar line of j in R: l = F^T x_j; distance of x_i to it.
    const Eigen::Vector3d l = F.transpose() * Eigen::Vector3d(xj.x(), xj.y(), 1.0);
    const double ln = std::sqrt(l.x() * l.x() + l.y() * l.y());
    if (ln < 1e-12) continue;
    int nc = 0;
    const int* cand = epi_bins_.candidates(l, &nc);
    // Candidates of R off the epipolar line (chi2 1 DoF, 95%) or far in scale are skipped.
    const BestTwo best = best_of(fc.desc_ptr(j), fr, cand, nc, bin, [&](int i) {
      const double e = (l.x() * fr.un[i].x + l.y() * fr.un[i].y + l.z()) / ln;
      return e * e > 3.84 * fr.scale[i] * fr.scale[i] ||
             (bin && std::abs(fr.level[i] - fc.level[j]) > 2);
    });
    if (rule.accepts(best)) claims_.offer(j, best.index, best.d1);
  }
}

bool Mapper::triangulate_match(const Keyframe& C, const Keyframe& R, int j, int i,
                               const cv::Mat& image, Eigen::Vector3d& p) {
  // One match (feature j of C, i of R): two-view triangulation, then the parallax, cheirality
  // and reprojection checks, then the third view (dynamic.check_new_points).
  const Features& fc = C.features;
  const Features& fr = R.features;
  const Eigen::Vector3d cc = C.T_cam_world.centre(), cr = R.T_cam_world.centre();
  const Eigen::Vector3d bj = K_.unproject(fc.un[j].x, fc.un[j].y);
  const Eigen::Vector3d bi = K_.unproject(fr.un[i].x, fr.un[i].y);
  // Rays must not be near-parallel (triangulation angle from the rays themselves).
  const Eigen::Vector3d rj = C.T_cam_world.R.transpose() * bj.normalized();
  const Eigen::Vector3d ri = R.T_cam_world.R.transpose() * bi.normalized();
  if (rj.dot(ri) > 0.99999) return false;
  if (!triangulate_dlt(R.T_cam_world, bi, C.T_cam_world, bj, p)) return false;
  if (parallax_cos(p, cr, cc) > std::cos(params_.min_parallax_deg * M_PI / 180.0)) return false;
  const Eigen::Vector3d pr = R.T_cam_world * p, pc = C.T_cam_world * p;
  if (pr.z() <= 0 || pc.z() <= 0) return false;
  const double er = (K_.project(pr) - Eigen::Vector2d(fr.un[i].x, fr.un[i].y)).squaredNorm();
  const double ej = (K_.project(pc) - Eigen::Vector2d(fc.un[j].x, fc.un[j].y)).squaredNorm();
  if (er > 5.991 * fr.scale[i] * fr.scale[i] || ej > 5.991 * fc.scale[j] * fc.scale[j]) {
    return false;
  }
  // A third view (dynamic.check_new_points): an object that moved between R and C.
  if (updater_ && !image.empty() &&
      !updater_->recent_frames_agree(p, image, Eigen::Vector2d(fc.kps[j].pt.x, fc.kps[j].pt.y),
                                     pc.z(), C.stamp_ns)) {
    ++stats_.points_rejected_new;
    return false;
  }
  return true;
}

int64_t Mapper::create_point(int kf_id, int rid, int j, int i, const Eigen::Vector3d& p) {
  // A new map point at p, observed by feature j of the candidate and feature i of keyframe
  // rid, with j's descriptor; created_kf_seq dates it for the recent-point culling.
  const Features& fc = map_.keyframe(kf_id)->features;
  MapPoint mp;
  mp.id = map_.next_point_id++;
  mp.p_world = p;
  mp.first_kf = rid < kf_id ? rid : kf_id;
  mp.created_kf_seq = map_.kf_seq;
  const size_t bytes = static_cast<size_t>(fc.desc.cols) * fc.desc.elemSize();
  mp.desc.assign(fc.desc_ptr(j), fc.desc_ptr(j) + bytes);
  const int64_t pid = mp.id;
  map_.points.emplace(pid, std::move(mp));
  map_.add_observation(pid, kf_id, j);
  map_.add_observation(pid, rid, i);
  return pid;
}

int Mapper::project_and_add(int64_t pid, int kf_id) {
  MapPoint* p = map_.point(pid);
  Keyframe* k = map_.keyframe(kf_id);
  if (!p || !k) return 0;
  for (const auto& o : p->obs) {
    if (o.kf == kf_id) return 0;
  }
  const Eigen::Vector3d pc = k->T_cam_world * p->p_world;
  if (pc.z() <= 1e-6) return 0;
  const Eigen::Vector2d uv = K_.project(pc);
  const Features& f = k->features;
  if (!camera_.ideal_in_image(uv)) return 0;
  const Eigen::Vector3d v = k->T_cam_world.centre() - p->p_world;
  const double dist = v.norm();
  const bool bin = fparams_.binary();
  if (bin && (dist < p->min_dist || dist > p->max_dist)) return 0;
  if (p->normal.dot(v) < 0.5 * dist) return 0;
  int lvl = 0, lo = -1, hi = 1 << 20;
  if (bin) {
    lvl = predict_level(p->max_dist, dist, std::log(std::max(1.0001, fparams_.scale_factor)),
                        fparams_.levels);
    lo = lvl - 1;
    hi = lvl + 1;
  }
  const double rad = 3.0 * std::pow(fparams_.scale_factor, lvl);
  const int n = f.radius_search(float(uv.x()), float(uv.y()), float(rad), lo, hi, cand_.data(),
                                static_cast<int>(cand_.size()));
  // Free features within the reprojection gate (chi2 2 DoF, 95%); the nearest descriptor.
  const BestTwo best = best_of(p->desc.data(), f, cand_.data(), n, bin, [&](int j) {
    return k->point_of[j] >= 0 || (Eigen::Vector2d(f.un[j].x, f.un[j].y) - uv).squaredNorm() >
                                      5.991 * f.scale[j] * f.scale[j];
  });
  if (!fparams_.matching.rule(MatchPurpose::kFuse, bin).accepts(best)) return 0;
  return map_.add_observation(pid, kf_id, best.index) ? 1 : 0;
}

int Mapper::fuse(int kf_id, const std::vector<int>& related) {
  int added = 0;
  Keyframe& C = *map_.keyframe(kf_id);
  // Points of the related keyframes (and their best neighbours) into the new keyframe.
  std::set<int> neighbourhood(related.begin(), related.end());
  for (int rid : related) {
    const auto cov = map_.covisible(rid);
    for (size_t k = 0; k < cov.size() && k < 5; ++k) neighbourhood.insert(cov[k].second);
  }
  neighbourhood.erase(kf_id);
  std::unordered_set<int64_t> seen;
  for (int64_t pid : C.point_of) {
    if (pid >= 0) seen.insert(pid);
  }
  for (int nid : neighbourhood) {
    const Keyframe* N = map_.keyframe(nid);
    if (!N) continue;
    for (int64_t pid : N->point_of) {
      if (pid < 0 || seen.count(pid)) continue;
      seen.insert(pid);
      added += project_and_add(pid, kf_id);
    }
  }
  // The new keyframe's points into the related keyframes.
  std::vector<int64_t> mine;
  for (int64_t pid : C.point_of) {
    if (pid >= 0) mine.push_back(pid);
  }
  for (int rid : related) {
    for (int64_t pid : mine) added += project_and_add(pid, rid);
  }
  return added;
}

void Mapper::update_descriptor(MapPoint& p) const {
  // The observation descriptor with the least median distance to the others (ORB-SLAM).
  const int n = static_cast<int>(p.obs.size());
  if (n < 3) return;
  std::vector<const uint8_t*> d;
  for (const auto& o : p.obs) {
    auto it = map_.keyframes.find(o.kf);
    if (it != map_.keyframes.end()) d.push_back(it->second.features.desc_ptr(o.feat));
  }
  const int m = static_cast<int>(d.size());
  if (m < 3) return;
  const bool bin = fparams_.binary();
  double best = 1e30;
  int bi = 0;
  std::vector<double> row(m);
  for (int a = 0; a < m; ++a) {
    for (int b = 0; b < m; ++b) row[b] = a == b ? 0.0 : descriptor_distance(d[a], d[b], bin);
    std::nth_element(row.begin(), row.begin() + (m - 1) / 2, row.end());
    if (row[(m - 1) / 2] < best) {
      best = row[(m - 1) / 2];
      bi = a;
    }
  }
  std::copy(d[bi], d[bi] + p.desc.size(), p.desc.begin());
}

void Mapper::handle_keyframe(const KeyframeCandidate& c) {
  // The keyframe path of Sec. 4, for a candidate that passed the tracker's conditions (m1):
  // insert it, triangulate new tracks with the related keyframes, keep it only under
  // condition m2, then fuse, refine the tracks, run local BA, cull and publish.
  int tracked = 0;
  const int id = insert_keyframe(c, &tracked);
  const std::vector<int> related = related_keyframes(id);
  std::vector<int64_t> created;
  const int n_new = triangulate(id, related, c.image, created);
  stats_.last_new_points = n_new;
  if (!accept_keyframe(id, n_new, tracked, created, c.image)) return;
  fuse(id, related);
  refine_new_tracks(created);
  update_keyframe_points(id);
  add_place(id);
  int kf = id;
  if (!kept_.empty() && try_merge(id, &kf)) {
    update_keyframe_points(kf);  // the fused points' geometry and descriptors
  }
  local_bundle_adjustment(kf);
  cull(kf);
  publish();
}

int Mapper::insert_keyframe(const KeyframeCandidate& c, int* tracked) {
  // The candidate enters the map as keyframe next_kf_id (not yet counted: condition m2 may
  // still remove it), with the observations of the map points the tracker matched in it.
  const int id = map_.next_kf_id;
  Keyframe& kf = map_.keyframes[id];
  kf.id = id;
  kf.stamp_ns = c.stamp_ns;
  kf.frame_no = c.frame_no;
  kf.T_cam_world = c.T_cam_world;
  kf.features.copy_from(c.features);
  kf.point_of.assign(c.features.count, -1);
  for (int j = 0; j < c.features.count && j < static_cast<int>(c.point_of.size()); ++j) {
    const int64_t pid = c.point_of[j];
    if (pid >= 0 && map_.add_observation(pid, id, j)) ++*tracked;
  }
  return id;
}

bool Mapper::accept_keyframe(int id, int n_new, int tracked, const std::vector<int64_t>& created,
                             const cv::Mat& image) {
  // Sec. 4 condition 3 (m2): only a frame contributing more than m2 new points becomes a
  // keyframe; otherwise it is discarded with the points it created. A weakly tracked frame
  // (m2_weak_tracking: fewer tracked points than m2) is kept when it contributes more new
  // points than it tracked.
  const int need = params_.m2_weak_tracking ? std::min(params_.m2, tracked) : params_.m2;
  if (n_new <= need) {
    for (int64_t pid : created) map_.erase_point(pid);
    map_.erase_keyframe(id);
    ++stats_.keyframes_rejected;
    return false;
  }
  ++map_.next_kf_id;
  ++map_.kf_seq;
  image.copyTo(map_.keyframes[id].image);
  ++stats_.keyframes_accepted;
  stats_.points_created += n_new;
  return true;
}

void Mapper::refine_new_tracks(const std::vector<int64_t>& created) {
  // Sec. 4's track equation: a new track seen in >= 3 views (after fusion) gets the position
  // minimising its reprojection error over all of them.
  std::vector<Pose> poses;
  std::vector<Eigen::Vector2d> obs;
  std::vector<double> sig;
  for (int64_t pid : created) {
    MapPoint* p = map_.point(pid);
    if (!p || p->obs.size() < 3) continue;
    poses.clear();
    obs.clear();
    sig.clear();
    for (const auto& o : p->obs) {
      const Keyframe& k = map_.keyframes.at(o.kf);
      poses.push_back(k.T_cam_world);
      obs.emplace_back(k.features.un[o.feat].x, k.features.un[o.feat].y);
      sig.push_back(k.features.scale[o.feat]);
    }
    Eigen::Vector3d x = p->p_world;
    if (refine_point(K_, poses.data(), obs.data(), sig.data(), static_cast<int>(poses.size()), x) >=
        0) {
      p->p_world = x;
    }
  }
}

void Mapper::update_keyframe_points(int id) {
  // Geometry (normal, distance range) and representative descriptor of every point the new
  // keyframe sees: its own, the tracked ones and the fused ones.
  for (int64_t pid : map_.keyframes.at(id).point_of) {
    if (pid < 0) continue;
    MapPoint* p = map_.point(pid);
    if (!p) continue;
    map_.update_point_geometry(*p, float(fparams_.scale_factor), fparams_.levels);
    update_descriptor(*p);
  }
}

void Mapper::local_bundle_adjustment(int id) {
  // Local BA (core/bundle_adjustment.h): the new keyframe and its most covisible keyframes,
  // ba.window in all; then the geometry of the points they see.
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<int> window{id};
  const int cap = params_.ba.window;
  const bool young = static_cast<int>(map_.keyframes.size()) < params_.ba_young_keyframes;
  const int base = young ? std::min(cap, params_.ba_young_window) : cap;
  const Keyframe* nk = map_.keyframe(id);
  int64_t lo = nk ? nk->frame_no : 0, hi = lo;
  for (const auto& [n, kid] : map_.covisible(id)) {
    const int size = static_cast<int>(window.size());
    if (size >= cap) break;
    if (size >= base && hi - lo >= params_.ba_young_span_frames) break;
    window.push_back(kid);
    if (const Keyframe* k = map_.keyframe(kid)) {
      lo = std::min(lo, k->frame_no);
      hi = std::max(hi, k->frame_no);
    }
  }
  stats_.last_ba_window = static_cast<int>(window.size());
  // Live pipeline (the tracker does not wait): the candidate being processed is still at the
  // ring's front, so a second one means the tracker has moved on and needs it mapped; BA yields
  // (the next keyframe's BA covers this window again). Lossless replay never queues a second.
  const auto waiting = [this] { return link_->candidates.size_approx() > 1; };
  if (params_.ba_yield && waiting()) {
    ++stats_.ba_yielded;
  } else if (bundle_adjust(map_, K_, window, params_.ba,
                           params_.ba_yield ? std::function<bool()>(waiting) : nullptr)
                 .stopped) {
    ++stats_.ba_yielded;
  }
  stats_.last_ba_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  for (int kid : window) {
    const Keyframe* k = map_.keyframe(kid);
    if (!k) continue;
    for (int64_t pid : k->point_of) {
      MapPoint* p = pid >= 0 ? map_.point(pid) : nullptr;
      if (p) map_.update_point_geometry(*p, float(fparams_.scale_factor), fparams_.levels);
    }
  }
}

void Mapper::cull(int kf_id) {
  // Culling after a new keyframe (bounded map): recent points, then redundant keyframes among
  // its neighbours, then the caps.
  cull_recent_points();
  cull_redundant_keyframes(kf_id);
  cap_keyframes(kf_id);
  cull_unobserved_points();
  cap_points();
}

void Mapper::cull_recent_points() {
  // A point seen by fewer than 2 keyframes, or still by at most 2 at the second or third
  // keyframe after the one that created it (ORB-SLAM's rule), goes.
  std::vector<int64_t> bad;
  for (const auto& [pid, p] : map_.points) {
    const int age = map_.kf_seq - p.created_kf_seq;
    if (p.obs.size() < 2 || (age >= 3 && age <= 4 && p.obs.size() <= 2)) bad.push_back(pid);
  }
  for (int64_t pid : bad) map_.erase_point(pid);
  stats_.points_culled += static_cast<int>(bad.size());
}

void Mapper::cull_redundant_keyframes(int kf_id) {
  // Sec. 4's 90% rule (Map::redundancy) among the new keyframe's covisible keyframes: one (not
  // fixed) whose points are invalid or seen by >= 3 other keyframes for more than
  // redundant_fraction of them goes. The map updater applies the same rule to the keyframes
  // whose points it checked.
  for (const auto& [n, kid] : map_.covisible(kf_id)) {
    Keyframe* k = map_.keyframe(kid);
    if (!k || k->fixed || kid == kf_id) continue;
    if (map_.redundancy(*k).exceeds(params_.redundant_fraction)) {
      retire_keyframe(kid);
      ++stats_.keyframes_culled;
    }
  }
}

void Mapper::retire_keyframe(int kid) {
  // With the trail on, a removed keyframe leaves its pose relative to the keyframe sharing most
  // points with it, so final_keyframe_pose() can place frames that referred to it.
  if (keep_trail_) {
    const Keyframe* k = map_.keyframe(kid);
    for (const auto& [n, pid] : map_.covisible(kid)) {
      const Keyframe* parent = map_.keyframe(pid);
      if (pid == kid || parent == nullptr) continue;
      trail_[kid] = Trail{pid, k->T_cam_world * parent->T_cam_world.inverse()};
      break;
    }
  }
  map_.erase_keyframe(kid);
}

bool Mapper::resolve_merges(uint32_t* epoch, int* id, double* scale) const {
  for (size_t hops = 0; hops <= merges_.size(); ++hops) {
    const auto m = merges_.find(*epoch);
    if (m == merges_.end()) return true;
    *id += m->second.kf_offset;
    *scale *= m->second.S.s;
    *epoch = m->second.into;
  }
  return false;
}

double Mapper::final_epoch_scale(uint32_t epoch) const {
  int id = 0;
  double scale = 1.0;
  return resolve_merges(&epoch, &id, &scale) ? scale : 1.0;
}

bool Mapper::final_frame_pose(const TrackResult& r, Pose* T_world_cam) const {
  Pose T_ref_world;
  if (r.ref_keyframe < 0 || !final_keyframe_pose(r.epoch, r.ref_keyframe, &T_ref_world)) {
    return false;
  }
  // A merged map epoch's relative poses are in its old scale (recovery).
  *T_world_cam = T_ref_world.inverse() *
                 Pose{r.q_ref_cam.toRotationMatrix(), r.p_ref_cam * final_epoch_scale(r.epoch)};
  return true;
}

std::vector<uint32_t> Mapper::kept_epochs() const {
  std::vector<uint32_t> out;
  for (const auto& k : kept_) out.push_back(k->epoch);
  return out;
}

bool Mapper::final_keyframe_pose(uint32_t epoch, int id, Pose* T_cam_world) const {
  // Through the merges to the map that holds the keyframe now: the current one or a kept one.
  double scale = 1.0;
  if (!resolve_merges(&epoch, &id, &scale)) return false;
  const Map* map = epoch == epoch_ ? &map_ : nullptr;
  const std::unordered_map<int, Trail>* trail = &trail_;
  for (const auto& k : kept_) {
    if (map == nullptr && k->epoch == epoch) {
      map = &k->map;
      trail = &k->trail;
    }
  }
  if (map == nullptr) return false;
  Pose T_id_cur;  // pose of keyframe `id` relative to the keyframe reached so far
  int cur = id;
  for (int hops = 0; hops <= static_cast<int>(trail->size()); ++hops) {
    if (const auto k = map->keyframes.find(cur); k != map->keyframes.end()) {
      *T_cam_world = T_id_cur * k->second.T_cam_world;
      return true;
    }
    const auto t = trail->find(cur);
    if (t == trail->end()) return false;
    T_id_cur = T_id_cur * t->second.T_kf_parent;
    cur = t->second.parent;
  }
  return false;
}

void Mapper::cap_keyframes(int kf_id) {
  // Above max_keyframes the oldest keyframe goes (never the new one); the oldest left becomes
  // the fixed gauge keyframe.
  while (static_cast<int>(map_.keyframes.size()) > params_.max_keyframes) {
    const int oldest = map_.keyframes.begin()->first;
    if (oldest == kf_id) break;
    retire_keyframe(oldest);
    ++stats_.keyframes_culled;
    if (!map_.keyframes.empty()) map_.keyframes.begin()->second.fixed = true;  // new gauge
  }
}

void Mapper::cull_unobserved_points() {
  // Points left with fewer than 2 observations by the keyframe culling go.
  std::vector<int64_t> bad;
  for (const auto& [pid, p] : map_.points) {
    if (p.obs.size() < 2) bad.push_back(pid);
  }
  for (int64_t pid : bad) map_.erase_point(pid);
  stats_.points_culled += static_cast<int>(bad.size());
}

void Mapper::cap_points() {
  // Above max_points the points with the fewest observations go, oldest (lowest id) first.
  if (static_cast<int>(map_.points.size()) <= params_.max_points) return;
  std::vector<std::pair<std::pair<size_t, int64_t>, int64_t>> order;
  for (const auto& [pid, p] : map_.points) order.push_back({{p.obs.size(), pid}, pid});
  std::sort(order.begin(), order.end());
  const size_t excess = map_.points.size() - static_cast<size_t>(params_.max_points);
  for (size_t i = 0; i < excess; ++i) map_.erase_point(order[i].second);
  stats_.points_culled += static_cast<int>(excess);
}

std::shared_ptr<MapSnapshot> Mapper::build_snapshot(const Map& m, uint32_t epoch) const {
  auto s = std::make_shared<MapSnapshot>();
  s->epoch = epoch;
  s->binary = fparams_.binary();
  std::unordered_map<int, int> kf_index;
  for (const auto& [id, k] : m.keyframes) {
    kf_index[id] = static_cast<int>(s->kf_ids.size());
    s->kf_ids.push_back(id);
    s->kf_pose.push_back(k.T_cam_world);
    // Points of the keyframe that are well established (ORB-SLAM: >= 3 observations once the
    // map has more than 2 keyframes): the tracker's keyframe rule compares against these.
    const size_t min_obs = m.keyframes.size() > 2 ? 3 : 2;
    int n = 0;
    for (int64_t pid : k.point_of) {
      if (pid < 0) continue;
      auto it = m.points.find(pid);
      n += it != m.points.end() && it->second.obs.size() >= min_obs;
    }
    s->kf_points.push_back(n);
  }
  const int cols = s->binary ? 32 : 128;
  const int type = s->binary ? CV_8U : CV_32F;
  int rows = 0;
  for (const auto& kv : m.points) rows += kv.second.valid && kv.second.obs.size() >= 2;
  s->desc.create(std::max(1, rows), cols, type);
  s->obs_start.push_back(0);
  s->row_of.reserve(static_cast<size_t>(rows) * 2);
  s->kf_row_start.assign(s->kf_ids.size() + 1, 0);
  for (const auto& [pid, p] : m.points) {
    if (!p.valid || p.obs.size() < 2) continue;
    const int r = static_cast<int>(s->ids.size());
    s->ids.push_back(pid);
    s->p_world.push_back(p.p_world);
    s->normal.push_back(p.normal.cast<float>());
    s->min_dist.push_back(p.min_dist);
    s->max_dist.push_back(p.max_dist);
    std::copy(p.desc.begin(), p.desc.end(), s->desc.ptr<uint8_t>(r));
    for (const auto& o : p.obs) {
      auto it = kf_index.find(o.kf);
      if (it == kf_index.end()) continue;
      s->obs_kf.push_back(it->second);
      ++s->kf_row_start[static_cast<size_t>(it->second) + 1];
    }
    s->obs_start.push_back(static_cast<int>(s->obs_kf.size()));
    s->row_of.emplace(pid, r);
  }
  // Each keyframe's rows (the inverse of obs_*), for relocalization against a few keyframes.
  for (size_t k = 1; k < s->kf_row_start.size(); ++k) s->kf_row_start[k] += s->kf_row_start[k - 1];
  s->kf_rows.resize(s->obs_kf.size());
  std::vector<int> fill(s->kf_row_start.begin(), s->kf_row_start.end() - 1);
  for (int r = 0; r < s->rows(); ++r) {
    for (int o = s->obs_start[size_t(r)]; o < s->obs_start[size_t(r) + 1]; ++o) {
      s->kf_rows[size_t(fill[size_t(s->obs_kf[size_t(o)])]++)] = r;
    }
  }
  if (!s->binary && rows > 0) {
    // The paper's KD-tree over the reference features (FLANN, randomised k-d trees).
    s->kdtree = std::make_unique<cv::flann::Index>(s->desc.rowRange(0, rows),
                                                   cv::flann::KDTreeIndexParams(4));
  }
  return s;
}

void Mapper::publish() {
  std::shared_ptr<MapSnapshot> s = build_snapshot(map_, epoch_);
  s->version = ++version_;
  if (places_) {
    places_->retain(epoch_, [&](int id) { return map_.keyframes.count(id) > 0; });
    s->places = places_->build();
  }
  for (const auto& k : kept_) s->kept.push_back(k->snapshot);
  s->merged_from = last_merged_from_;
  s->merge_scale = last_merge_.S.s;
  s->merge_R = last_merge_.S.R;
  s->merge_t = last_merge_.S.t;
  s->merge_point_offset = last_merge_.point_offset;
  if (link_->debug_recent_invalid.load(std::memory_order_relaxed) > 0) fill_recent_invalid(*s);
  link_->keyframes.store(static_cast<int>(map_.keyframes.size()));
  link_->points.store(s->rows());
  link_->index.publish(std::move(s));
  ++stats_.snapshots;
}

void Mapper::start_epoch(uint32_t epoch) {
  // A reset candidate: the current map is kept frozen (or dropped when tiny) and an empty map
  // of the new epoch waits for the tracker's initialization.
  freeze_current();
  map_ = Map();
  trail_.clear();
  if (updater_) updater_->reset();
  epoch_ = epoch;
  last_merged_from_ = -1;
  link_->keyframes.store(0);
  link_->points.store(0);
  // With earlier maps kept, an empty snapshot of the new epoch carries them to the tracker,
  // which tries to relocalize into them while it initializes.
  if (!kept_.empty()) publish();
}

void Mapper::freeze_current() {
  // Keep the current map (more than 2 keyframes, max_epochs > 0, place recognition: ORB with a
  // vocabulary), frozen, with its places and last snapshot; the oldest kept map goes above
  // max_epochs. Otherwise the map is dropped.
  const bool keep = places_ != nullptr && params_.max_epochs > 0 && map_.keyframes.size() > 2;
  if (!keep) {
    if (places_) places_->retain(epoch_, [](int) { return false; });
    return;
  }
  auto k = std::make_unique<KeptMap>();
  k->epoch = epoch_;
  std::shared_ptr<MapSnapshot> snap = build_snapshot(map_, epoch_);
  if (places_) {
    places_->retain(epoch_, [&](int id) { return map_.keyframes.count(id) > 0; });
    snap->places = places_->build();
  }
  k->snapshot = std::move(snap);
  k->map = std::move(map_);
  k->trail = std::move(trail_);
  kept_.push_back(std::move(k));
  ++stats_.maps_kept;
  RDSLAM_LOG_INFO("mapper: map epoch %u kept (%zu keyframes, %zu points; %zu earlier maps)", epoch_,
                  kept_.back()->map.keyframes.size(), kept_.back()->map.points.size(),
                  kept_.size());
  while (static_cast<int>(kept_.size()) > params_.max_epochs) {
    const uint32_t e = kept_.front()->epoch;
    if (places_) places_->retain(e, [](int) { return false; });
    kept_.erase(kept_.begin());
    ++stats_.maps_dropped;
  }
}

bool Mapper::reactivate(uint32_t epoch) {
  // The tracker relocalized into kept map `epoch`: it becomes the current map again.
  auto it = std::find_if(kept_.begin(), kept_.end(),
                         [epoch](const std::unique_ptr<KeptMap>& k) { return k->epoch == epoch; });
  if (it == kept_.end()) return false;
  std::unique_ptr<KeptMap> k = std::move(*it);
  kept_.erase(it);
  freeze_current();
  map_ = std::move(k->map);
  trail_ = std::move(k->trail);
  epoch_ = epoch;
  last_merged_from_ = -1;
  if (updater_) updater_->reset();
  ++stats_.maps_reactivated;
  RDSLAM_LOG_INFO("mapper: map epoch %u is current again", epoch);
  return true;
}

bool Mapper::try_merge(int kf, int* merged_kf) {
  // Place recognition of the new keyframe in each kept map (newest first), then geometric
  // verification; the first verified candidate is merged.
  const Keyframe* A = map_.keyframe(kf);
  if (!places_ || A == nullptr) return false;
  link_->vocabulary->transform(A->features, bow_, voc_scratch_);
  const std::shared_ptr<const KeyframeDatabase> db = places_->build();
  for (size_t i = kept_.size(); i-- > 0;) {
    PlaceQueryParams qp;
    qp.max_candidates = 3;
    qp.epoch = kept_[i]->epoch;
    PlaceCandidate cands[3];
    const int n = db->query(bow_, qp, merge_query_, cands, 3);
    for (int c = 0; c < n; ++c) {
      const Keyframe* B = kept_[i]->map.keyframe(cands[c].keyframe);
      if (B == nullptr) continue;
      ++stats_.merge_attempts;
      Sim3 S;
      std::vector<std::pair<int, int64_t>> matches;
      if (!verify_merge(*A, *B, kept_[i]->map, &S, &matches)) continue;
      merge_into(i, S, matches, kf, merged_kf);
      return true;
    }
  }
  return false;
}

bool Mapper::verify_merge(const Keyframe& A, const Keyframe& B, const Map& target, Sim3* S,
                          std::vector<std::pair<int, int64_t>>* matches) const {
  // 1. Descriptor matches between A's and B's features that have map points (2-NN with the
  //    relocalization rule, one-to-one), as 3D-3D pairs; 2. Sim(3) RANSAC; 3. the points of B
  //    and its covisible keyframes projected into A under S must match enough features.
  const bool bin = fparams_.binary();
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kRelocalize, bin);
  std::vector<int> b_feats;
  for (int i = 0; i < B.features.count; ++i) {
    const int64_t pid = B.point_of[size_t(i)];
    const auto it = pid >= 0 ? target.points.find(pid) : target.points.end();
    if (it != target.points.end() && it->second.valid) b_feats.push_back(i);
  }
  std::vector<Sim3Pair, Eigen::aligned_allocator<Sim3Pair>> pairs;
  std::vector<int> pair_feat;
  std::unordered_map<int, std::pair<double, size_t>> claimed;  // B feature -> (distance, pair)
  for (int j = 0; j < A.features.count; ++j) {
    const int64_t pid = A.point_of[size_t(j)];
    const auto pa = pid >= 0 ? map_.points.find(pid) : map_.points.end();
    if (pa == map_.points.end() || !pa->second.valid) continue;
    const BestTwo best = best_of(A.features.desc_ptr(j), B.features, b_feats.data(),
                                 static_cast<int>(b_feats.size()), bin);
    if (!rule.accepts(best)) continue;
    const int i = best.index;
    const MapPoint& pb = target.points.at(B.point_of[size_t(i)]);
    Sim3Pair q;
    q.a = pa->second.p_world;
    q.b = pb.p_world;
    q.xa = Eigen::Vector2d(A.features.un[size_t(j)].x, A.features.un[size_t(j)].y);
    q.xb = Eigen::Vector2d(B.features.un[size_t(i)].x, B.features.un[size_t(i)].y);
    q.sa = A.features.scale[size_t(j)];
    q.sb = B.features.scale[size_t(i)];
    const auto c = claimed.find(i);
    if (c != claimed.end()) {
      if (c->second.first <= best.d1) continue;
      pairs[c->second.second] = q;  // a closer feature of A takes B's feature
      pair_feat[c->second.second] = j;
      c->second.first = best.d1;
      continue;
    }
    claimed[i] = {best.d1, pairs.size()};
    pairs.push_back(q);
    pair_feat.push_back(j);
  }
  Sim3RansacParams rp;
  rp.min_inliers = params_.merge_min_inliers;
  std::vector<uint8_t> inl;
  const int n_inl = estimate_sim3(pairs, A.T_cam_world, B.T_cam_world, K_, rp, S, &inl);
  if (n_inl < params_.merge_min_inliers) return false;
  const int m = match_by_projection(A, B, target, *S, matches);
  RDSLAM_LOG_INFO(
      "mapper: merge check of keyframe %d (epoch %u) with an earlier map's keyframe "
      "%d: %zu pairs, %d Sim(3) inliers (scale %.3f), %d matched by projection",
      A.id, epoch_, B.id, pairs.size(), n_inl, S->s, m);
  return m >= params_.merge_min_matches;
}

int Mapper::match_by_projection(const Keyframe& A, const Keyframe& B, const Map& target,
                                const Sim3& S,
                                std::vector<std::pair<int, int64_t>>* matches) const {
  // The valid points of B and of its 10 most covisible keyframes (target map), projected into
  // A (its pose in the target frame under S), matched in a radius of 5 px x the predicted
  // level's scale by descriptor (MatchPurpose::kFuse), one point per feature of A.
  const bool bin = fparams_.binary();
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kFuse, bin);
  const Pose Ta = S.camera(A.T_cam_world);
  const Eigen::Vector3d ca = Ta.centre();
  std::vector<int> kfs{B.id};
  for (const auto& [n, kid] : target.covisible(B.id)) {
    if (kfs.size() >= 11) break;
    kfs.push_back(kid);
  }
  std::unordered_set<int64_t> seen;
  std::unordered_map<int, std::pair<double, int64_t>> best_of_feat;
  std::vector<int> cand(512);
  const double log_sf = std::log(std::max(1.0001, fparams_.scale_factor));
  for (int kid : kfs) {
    const auto k = target.keyframes.find(kid);
    if (k == target.keyframes.end()) continue;
    for (int64_t pid : k->second.point_of) {
      if (pid < 0 || !seen.insert(pid).second) continue;
      const auto it = target.points.find(pid);
      if (it == target.points.end() || !it->second.valid) continue;
      const MapPoint& p = it->second;
      const Eigen::Vector3d pc = Ta * p.p_world;
      if (pc.z() <= 1e-6) continue;
      const Eigen::Vector2d uv = K_.project(pc);
      if (!camera_.ideal_in_image(uv)) continue;
      const double dist = (ca - p.p_world).norm();
      int lvl = 0;
      if (bin) lvl = predict_level(p.max_dist, dist, log_sf, std::max(1, fparams_.levels));
      const double r = 5.0 * std::pow(fparams_.scale_factor, lvl);
      const int n = A.features.radius_search(float(uv.x()), float(uv.y()), float(r),
                                             bin ? lvl - 1 : -1, bin ? lvl + 1 : 1 << 20,
                                             cand.data(), static_cast<int>(cand.size()));
      const BestTwo best = best_of(p.desc.data(), A.features, cand.data(), n, bin);
      if (!rule.accepts(best)) continue;
      auto [slot, fresh] = best_of_feat.emplace(best.index, std::make_pair(best.d1, pid));
      if (!fresh && best.d1 < slot->second.first) slot->second = {best.d1, pid};
    }
  }
  matches->clear();
  for (const auto& [j, dp] : best_of_feat) matches->emplace_back(j, dp.second);
  std::sort(matches->begin(), matches->end());
  return static_cast<int>(matches->size());
}

void Mapper::merge_into(size_t kept_index, const Sim3& S,
                        const std::vector<std::pair<int, int64_t>>& matches, int kf,
                        int* merged_kf) {
  // The current map moves into kept map `kept_index` under S (core/map_merge.h); the features
  // of keyframe `kf` matched by projection fuse their points with the earlier map's (or, without
  // a point, observe the earlier map's point). The merged map keeps the earlier epoch.
  std::unique_ptr<KeptMap> k = std::move(kept_[kept_index]);
  kept_.erase(kept_.begin() + static_cast<long>(kept_index));
  const uint32_t from = epoch_;
  const Keyframe& A = map_.keyframes.at(kf);
  std::vector<std::pair<int64_t, int64_t>> fuse;
  std::vector<std::pair<int, int64_t>> observe;
  for (const auto& [j, pid] : matches) {
    const int64_t own = A.point_of[size_t(j)];
    if (own >= 0) {
      fuse.emplace_back(own, pid);
    } else {
      observe.emplace_back(j, pid);
    }
  }
  if (places_) places_->retain(from, [](int) { return false; });
  // Trails of removed keyframes follow (relative poses: translation scaled by s).
  for (const auto& [kid, t] : trail_) {
    // Ids shift by the target's next keyframe id (merge_maps' offset, read before it).
    Trail moved = t;
    moved.parent += k->map.next_kf_id;
    moved.T_kf_parent.t *= S.s;
    k->trail[kid + k->map.next_kf_id] = moved;
  }
  int kf_offset = 0;
  int64_t point_offset = 0;
  const int fused = merge_maps(k->map, std::move(map_), S, fuse, &kf_offset, &point_offset);
  for (const auto& [j, pid] : observe) k->map.add_observation(pid, kf + kf_offset, j);
  map_ = std::move(k->map);
  trail_ = std::move(k->trail);
  epoch_ = k->epoch;
  if (updater_) updater_->reset();
  MergeRecord rec;
  rec.into = epoch_;
  rec.S = S;
  rec.kf_offset = kf_offset;
  rec.point_offset = point_offset;
  merges_[from] = rec;
  last_merge_ = rec;
  last_merged_from_ = from;
  for (const auto& [id, kfr] : map_.keyframes) {
    if (id >= kf_offset) add_place(id);
  }
  *merged_kf = kf + kf_offset;
  ++stats_.merges;
  link_->merges.fetch_add(1, std::memory_order_relaxed);
  RDSLAM_LOG_INFO(
      "mapper: map epoch %u merged into epoch %u (scale %.3f; %d points fused, %zu "
      "observations added)",
      from, epoch_, S.s, fused, observe.size());
}

void Mapper::fill_recent_invalid(MapSnapshot& s) {
  // Debug output (core/debug_frame.h): every point found invalid (V(X) = 0, whichever rule
  // set it) that was not listed before, newest last, bounded. Costs one pass over the map per
  // publish, only when the debug output is on.
  const size_t cap = static_cast<size_t>(link_->debug_recent_invalid.load());
  if (recent_invalid_epoch_ != epoch_) {  // a new map reuses point ids
    recent_invalid_.clear();
    invalid_seen_.clear();
    recent_invalid_epoch_ = epoch_;
  }
  for (const auto& [pid, p] : map_.points) {
    if (p.valid || !invalid_seen_.insert(pid).second) continue;
    recent_invalid_.emplace_back(pid, p.p_world);
  }
  while (recent_invalid_.size() > cap) recent_invalid_.pop_front();
  if (invalid_seen_.size() > 8 * cap + 1024) {
    // Forget ids that left the map (culled); they cannot turn invalid again.
    for (auto it = invalid_seen_.begin(); it != invalid_seen_.end();) {
      it = map_.points.count(*it) ? std::next(it) : invalid_seen_.erase(it);
    }
  }
  s.invalid_ids.reserve(recent_invalid_.size());
  s.invalid_p_world.reserve(recent_invalid_.size());
  for (const auto& [pid, p] : recent_invalid_) {
    s.invalid_ids.push_back(pid);
    s.invalid_p_world.push_back(p);
  }
}

}  // namespace rdslam
