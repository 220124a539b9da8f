#include "drivers/synth_scene.h"

#include <yaml-cpp/yaml.h>

#include <sys/stat.h>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>

namespace rdslam {

namespace {

constexpr double kPi = 3.14159265358979323846;
double deg2rad(double d) {
  return d * kPi / 180.0;
}

[[noreturn]] void fail(const std::string& origin, const std::string& what) {
  throw std::runtime_error("synth scenario '" + origin + "': " + what);
}

bool file_exists(const std::string& p) {
  struct stat st;
  return ::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

// ---- YAML helpers: every read names its key in the error ----
struct Reader {
  std::string origin;

  double num(const YAML::Node& n, const char* key, double def, double lo, double hi) const {
    if (!n || !n[key]) return def;
    double v;
    try {
      v = n[key].as<double>();
    } catch (const YAML::Exception&) {
      fail(origin, std::string(key) + ": expected a number");
    }
    if (!(v >= lo && v <= hi)) {
      std::ostringstream os;
      os << key << ": value " << v << " out of range [" << lo << ", " << hi << "]";
      fail(origin, os.str());
    }
    return v;
  }
  int integer(const YAML::Node& n, const char* key, int def, int lo, int hi) const {
    return static_cast<int>(std::lround(num(n, key, def, lo, hi)));
  }
  bool boolean(const YAML::Node& n, const char* key, bool def) const {
    if (!n || !n[key]) return def;
    try {
      return n[key].as<bool>();
    } catch (const YAML::Exception&) {
      fail(origin, std::string(key) + ": expected true or false");
    }
  }
  std::string str(const YAML::Node& n, const char* key, const std::string& def) const {
    if (!n || !n[key]) return def;
    try {
      return n[key].as<std::string>();
    } catch (const YAML::Exception&) {
      fail(origin, std::string(key) + ": expected a string");
    }
  }
  Eigen::Vector3d vec3(const YAML::Node& n, const char* key, const Eigen::Vector3d& def) const {
    if (!n || !n[key]) return def;
    const YAML::Node v = n[key];
    if (!v.IsSequence() || v.size() != 3) fail(origin, std::string(key) + ": expected [x, y, z]");
    try {
      return {v[0].as<double>(), v[1].as<double>(), v[2].as<double>()};
    } catch (const YAML::Exception&) {
      fail(origin, std::string(key) + ": expected three numbers");
    }
  }
  std::vector<std::string> strings(const YAML::Node& n, const char* key,
                                   const std::vector<std::string>& def) const {
    if (!n || !n[key]) return def;
    const YAML::Node v = n[key];
    if (v.IsScalar()) return {v.as<std::string>()};
    if (!v.IsSequence() || v.size() == 0) fail(origin, std::string(key) + ": expected a list");
    std::vector<std::string> out;
    for (const auto& e : v) out.push_back(e.as<std::string>());
    return out;
  }
  std::pair<int, int> range(const YAML::Node& n, const char* key, std::pair<int, int> def) const {
    if (!n || !n[key]) return def;
    const YAML::Node v = n[key];
    if (!v.IsSequence() || v.size() != 2) fail(origin, std::string(key) + ": expected [from, to]");
    try {
      const int a = v[0].as<int>();
      const int b = v[1].as<int>() < 0 ? INT_MAX : v[1].as<int>();
      if (b < a) fail(origin, std::string(key) + ": range end before start");
      return {a, b};
    } catch (const YAML::Exception&) {
      fail(origin, std::string(key) + ": expected two integers");
    }
  }
  // Rejects keys a section does not know, so a typo is an error rather than a silent default.
  void known(const YAML::Node& n, const char* section, std::initializer_list<const char*> keys) {
    if (!n) return;
    if (!n.IsMap()) fail(origin, std::string(section) + ": expected a mapping");
    for (const auto& kv : n) {
      const std::string k = kv.first.as<std::string>();
      bool ok = false;
      for (const char* a : keys) ok = ok || k == a;
      if (!ok) fail(origin, std::string(section) + "." + k + ": unknown key");
    }
  }
};

Eigen::Matrix3d rpy_matrix(const Eigen::Vector3d& rpy_rad) {
  return (Eigen::AngleAxisd(rpy_rad.z(), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy_rad.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy_rad.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Isometry3d make_pose(const Eigen::Vector3d& xyz, const Eigen::Vector3d& rpy_deg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rpy_matrix({deg2rad(rpy_deg.x()), deg2rad(rpy_deg.y()), deg2rad(rpy_deg.z())});
  T.translation() = xyz;
  return T;
}

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

Eigen::Isometry3d interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double w) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const Eigen::Quaterniond qa(a.linear()), qb(b.linear());
  T.linear() = qa.slerp(w, qb).toRotationMatrix();
  T.translation() = (1.0 - w) * a.translation() + w * b.translation();
  return T;
}

// Camera orientation looking from p at target with world z up: camera z forward, x right,
// y down (OpenCV).
Eigen::Matrix3d look_at(const Eigen::Vector3d& p, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - p).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ());
  if (x.norm() < 1e-6) x = Eigen::Vector3d::UnitX();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = y;
  R.col(2) = z;
  return R;
}

// ---- geometry builders ----
using QuadVec = std::vector<SynthQuad, Eigen::aligned_allocator<SynthQuad>>;

SynthQuad quad(const Eigen::Vector3d& p0, const Eigen::Vector3d& u, const Eigen::Vector3d& v,
               int tex, double albedo) {
  SynthQuad q;
  q.p0 = p0;
  q.u = u;
  q.v = v;
  q.texture = tex;
  q.albedo = albedo;
  return q;
}

// Axis-aligned box in the object frame: x in [-a/2, a/2] + c.x, y likewise, z in
// [c.z, c.z + h]. Faces: 0 front (-y), 1 back (+y), 2 left (-x), 3 right (+x), 4 top, 5 bottom.
void add_box(QuadVec& out, const Eigen::Vector3d& size, const Eigen::Vector3d& c, const int tex[6],
             double albedo) {
  const double a = size.x(), b = size.y(), h = size.z();
  const double x0 = c.x() - a / 2, x1 = c.x() + a / 2, y0 = c.y() - b / 2, y1 = c.y() + b / 2;
  const double z0 = c.z(), z1 = c.z() + h;
  using V = Eigen::Vector3d;
  out.push_back(quad(V(x0, y0, z1), V(a, 0, 0), V(0, 0, -h), tex[0], albedo));
  out.push_back(quad(V(x1, y1, z1), V(-a, 0, 0), V(0, 0, -h), tex[1], albedo));
  out.push_back(quad(V(x0, y1, z1), V(0, -b, 0), V(0, 0, -h), tex[2], albedo));
  out.push_back(quad(V(x1, y0, z1), V(0, b, 0), V(0, 0, -h), tex[3], albedo));
  out.push_back(quad(V(x0, y1, z1), V(a, 0, 0), V(0, -b, 0), tex[4], albedo));
  out.push_back(quad(V(x0, y0, z0), V(a, 0, 0), V(0, b, 0), tex[5], albedo));
}

// A wall seen from inside the room, split into panels (posters) of about `panel` metres.
void add_panels(QuadVec& out, const Eigen::Vector3d& top_left, const Eigen::Vector3d& right,
                const Eigen::Vector3d& down, double width, double height, double panel,
                const std::vector<int>& texs, std::mt19937_64& rng, double albedo) {
  const int nx = std::max(1, static_cast<int>(std::lround(width / panel)));
  const int ny = std::max(1, static_cast<int>(std::lround(height / panel)));
  const double pw = width / nx, ph = height / ny;
  std::uniform_int_distribution<size_t> pick(0, texs.size() - 1);
  std::uniform_real_distribution<double> shade(0.85, 1.1);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      // Two draws in one argument list would be evaluated in an unspecified order (GCC:
      // right to left on x86-64, left to right on aarch64, so the walls differed between
      // the two). Sequenced here in the order x86-64 had, so its scenes stay the same.
      const double gain = shade(rng);
      const int tex = texs[pick(rng)];
      SynthQuad q = quad(top_left + right * (i * pw) + down * (j * ph), right * pw, down * ph, tex,
                         albedo * gain);
      out.push_back(q);
    }
  }
}

// ---- trajectory ----
struct Shake {
  // Hand-held jitter: per degree of freedom, three sinusoids with seeded frequencies and
  // phases (smooth, band-limited like a hand's tremor and sway).
  double freq[6][3], phase[6][3], amp[6][3];
  explicit Shake(uint64_t seed, double scale) {
    std::mt19937_64 rng(seed * 7919 + 17);
    std::uniform_real_distribution<double> f(0.3, 2.2), ph(0, 2 * kPi), a(0.5, 1.0);
    for (int d = 0; d < 6; ++d) {
      for (int k = 0; k < 3; ++k) {
        freq[d][k] = f(rng);
        phase[d][k] = ph(rng);
        // translation: ~4 mm; rotation: ~0.3 degrees, split over the three sinusoids.
        const double base = d < 3 ? 0.004 : deg2rad(0.3);
        amp[d][k] = scale * base * a(rng) / 2.0;
      }
    }
  }
  double eval(int d, double t) const {
    double s = 0;
    for (int k = 0; k < 3; ++k) s += amp[d][k] * std::sin(2 * kPi * freq[d][k] * t + phase[d][k]);
    return s;
  }
};

double camera_time(const SynthScene& sc, double frame) {
  // Pauses freeze the camera's clock: the camera stands still, shake included.
  double paused = 0;
  for (const auto& p : sc.trajectory.pauses) {
    if (frame > p.first) paused += std::min(frame, static_cast<double>(p.second)) - p.first;
  }
  return (frame - paused) / sc.fps;
}

// Roll/pitch/yaw swings in the camera frame (rpy and forward trajectories): roll about the
// optical axis (z), pitch about x, yaw about y, with fixed incommensurate periods.
Eigen::Matrix3d camera_swing(const Eigen::Vector3d& amp_deg, double t) {
  const Eigen::Vector3d& a = amp_deg;
  return (Eigen::AngleAxisd(deg2rad(a.y()) * std::sin(2 * kPi * t / 5.3),
                            Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(deg2rad(a.z()) * std::sin(2 * kPi * t / 7.1),
                            Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(deg2rad(a.x()) * std::sin(2 * kPi * t / 4.3), Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

Eigen::Isometry3d eval_camera(const SynthScene& sc, const Shake& shake, double frame) {
  const SynthTrajectorySpec& tr = sc.trajectory;
  const double t = camera_time(sc, frame);
  Eigen::Vector3d p = tr.center;
  Eigen::Matrix3d R;
  if (tr.type == "forward") {
    // Driving: along the direction of travel at speed_m_s, plus sinusoidal offsets in the
    // path frame (right, forward, up); the camera looks along the direction of travel, with
    // roll/pitch/yaw swings on top.
    const Eigen::Vector3d fwd = (tr.target - tr.center).normalized();
    Eigen::Vector3d right = fwd.cross(Eigen::Vector3d::UnitZ());
    if (right.norm() < 1e-6) right = Eigen::Vector3d::UnitX();
    right.normalize();
    const Eigen::Vector3d up = right.cross(fwd);
    Eigen::Vector3d off;
    for (int i = 0; i < 3; ++i) off[i] = tr.amplitude_m[i] * std::sin(2 * kPi * t / tr.period_s[i]);
    p += (tr.speed_m_s * t + off.y()) * fwd + off.x() * right + off.z() * up;
    R = look_at(p, p + fwd) * camera_swing(tr.rpy_amp_deg, t);
  } else if (tr.type == "turn") {
    // A robot: drive, turn on the spot, drive on (SynthTrajectorySpec). Each leg is a
    // smoothstep in time (starts and stops at rest).
    const double v = std::max(1e-9, tr.speed_m_s);
    const double t_in = tr.drive_m.x() / v;
    const double t_turn = std::abs(tr.turn_deg) / std::max(1e-9, tr.turn_rate_deg_s);
    const double t_out = tr.drive_m.y() / v;
    auto leg = [](double t0, double dur, double tt) {
      return dur <= 0 ? (tt >= t0 ? 1.0 : 0.0) : smoothstep(std::clamp((tt - t0) / dur, 0.0, 1.0));
    };
    Eigen::Vector3d fwd0 = tr.target - tr.center;
    fwd0.z() = 0;
    fwd0 = fwd0.norm() < 1e-9 ? Eigen::Vector3d::UnitY() : fwd0.normalized();
    const double yaw = deg2rad(tr.turn_deg) * leg(t_in, t_turn, t);
    const Eigen::Matrix3d Rz = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d fwd1 =
        Eigen::AngleAxisd(deg2rad(tr.turn_deg), Eigen::Vector3d::UnitZ()) * fwd0;
    const Eigen::Vector3d axis = tr.center + tr.drive_m.x() * leg(0, t_in, t) * fwd0 +
                                 tr.drive_m.y() * leg(t_in + t_turn, t_out, t) * fwd1;
    const Eigen::Vector3d h = Rz * fwd0;
    p = axis + tr.axis_offset_m * h;
    R = look_at(p, p + h);
  } else if (tr.type == "xyz") {
    for (int i = 0; i < 3; ++i) p[i] += tr.amplitude_m[i] * std::sin(2 * kPi * t / tr.period_s[i]);
    R = look_at(p, tr.target);
  } else if (tr.type == "path") {
    // Camera centre keys (frame, position), linear between them, plus the xyz sinusoids.
    const double f = t * sc.fps;
    const auto& k = tr.path;
    const bool keyed_target = tr.path_target.size() == k.size();
    Eigen::Vector3d target = keyed_target ? tr.path_target.front() : tr.target;
    p = k.front().second;
    for (size_t i = 0; i < k.size(); ++i) {
      if (f < k[i].first) break;
      p = k[i].second;
      if (keyed_target) target = tr.path_target[i];
      if (i + 1 < k.size() && f < k[i + 1].first) {
        const double w = (f - k[i].first) / (k[i + 1].first - k[i].first);
        p = (1.0 - w) * k[i].second + w * k[i + 1].second;
        if (keyed_target) target = (1.0 - w) * tr.path_target[i] + w * tr.path_target[i + 1];
      }
    }
    for (int i = 0; i < 3; ++i) p[i] += tr.amplitude_m[i] * std::sin(2 * kPi * t / tr.period_s[i]);
    R = look_at(p, target);
  } else if (tr.type == "halfsphere") {
    const double az = deg2rad(tr.azimuth_deg) * std::sin(2 * kPi * t / tr.azimuth_period_s);
    const double el = deg2rad(tr.elevation_deg) +
                      deg2rad(tr.elevation_amp_deg) * std::sin(2 * kPi * t / tr.elevation_period_s);
    p = tr.target + tr.radius_m * Eigen::Vector3d(std::cos(el) * std::sin(az),
                                                  -std::cos(el) * std::cos(az), std::sin(el));
    R = look_at(p, tr.target);
  } else if (tr.type == "rpy") {
    for (int i = 0; i < 3; ++i) p[i] += 0.03 * std::sin(2 * kPi * t / tr.period_s[i]);
    R = look_at(p, tr.target) * camera_swing(tr.rpy_amp_deg, t);
  } else {  // static
    R = look_at(p, tr.target);
  }
  if (tr.shake > 0) {
    p += Eigen::Vector3d(shake.eval(0, t), shake.eval(1, t), shake.eval(2, t));
    R = R * rpy_matrix({shake.eval(5, t), shake.eval(3, t), shake.eval(4, t)});
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

Eigen::Isometry3d eval_object(const SynthScene& sc, const SynthObject& o, double frame) {
  Eigen::Isometry3d T = o.pose0;
  for (const auto& m : o.moves) {
    if (frame >= m.end) {
      T = m.to;
      continue;
    }
    if (frame > m.start) {
      const double x = (frame - m.start) / std::max(1, m.end - m.start);
      T = interpolate(T, m.to, m.linear ? x : smoothstep(x));
    }
    break;
  }
  const SynthWobble& w = o.wobble;
  if (w.enabled && frame > w.start && frame < w.end) {
    const double t = (frame - w.start) / sc.fps;
    const double fade_frames = std::max(1e-9, w.fade_s * sc.fps);
    const double env = smoothstep((frame - w.start) / fade_frames) *
                       (w.end == INT_MAX ? 1.0 : smoothstep((w.end - frame) / fade_frames));
    const double ph = 2 * kPi * t / w.period_s;
    // Different phases per axis so the motion is a 6-DoF loop, not a line.
    const Eigen::Vector3d dp(w.amplitude_m.x() * std::sin(ph),
                             w.amplitude_m.y() * std::sin(ph + 1.3),
                             w.amplitude_m.z() * std::sin(2 * ph + 0.4));
    const Eigen::Vector3d dr(w.amplitude_rad.x() * std::sin(ph + 0.7),
                             w.amplitude_rad.y() * std::sin(ph + 2.1),
                             w.amplitude_rad.z() * std::sin(ph + 2.9));
    Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
    D.linear() = rpy_matrix(env * dr);
    D.translation() = env * dp;
    T = T * D;
  }
  return T;
}

bool poses_differ(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm() > 1e-9 ||
         (a.linear() - b.linear()).cwiseAbs().maxCoeff() > 1e-9;
}

// ---- texture registry ----
struct TextureTable {
  std::string origin;
  std::string dir;
  std::vector<SynthTextureSpec>* specs;
  std::map<std::string, int> index;

  std::string resolve(const std::string& name) const {
    if (name.find('/') != std::string::npos) {
      if (file_exists(name)) return name;
      fail(origin, "texture file not found: " + name);
    }
    for (const char* ext : {"", ".jpg", ".png"}) {
      const std::string p = dir + "/" + name + ext;
      if (file_exists(p)) return p;
    }
    fail(origin, "texture '" + name + "' not found in " + dir);
  }
  int get(const std::string& name, double contrast, double blur) {
    std::ostringstream key;
    key << name << '|' << contrast << '|' << blur;
    auto it = index.find(key.str());
    if (it != index.end()) return it->second;
    SynthTextureSpec s;
    s.path = resolve(name);
    s.contrast = contrast;
    s.blur_px = blur;
    specs->push_back(s);
    const int id = static_cast<int>(specs->size()) - 1;
    index[key.str()] = id;
    return id;
  }
};

void derive(SynthScene& sc) {
  const int n = sc.frame_count;
  const Shake shake(sc.seed, sc.trajectory.shake);
  sc.T_world_cam.resize(n);
  for (int f = 0; f < n; ++f) sc.T_world_cam[f] = eval_camera(sc, shake, f);
  sc.exposure.assign(n, 1.0);
  if (!sc.exposure_keys.empty()) {
    auto keys = sc.exposure_keys;
    std::sort(keys.begin(), keys.end());
    for (int f = 0; f < n; ++f) {
      double g = keys.front().second;
      for (size_t k = 0; k + 1 < keys.size(); ++k) {
        if (f >= keys[k].first && f <= keys[k + 1].first) {
          const double w = (f - keys[k].first) /
                           std::max(1.0, static_cast<double>(keys[k + 1].first - keys[k].first));
          g = (1 - w) * keys[k].second + w * keys[k + 1].second;
          break;
        }
        if (f > keys[k + 1].first) g = keys[k + 1].second;
      }
      sc.exposure[f] = g;
    }
  }
  sc.events.clear();
  for (auto& o : sc.objects) {
    o.poses.resize(n);
    o.moving.assign(n, 0);
    o.first_change = INT_MAX;
    for (int f = 0; f < n; ++f) {
      o.poses[f] = eval_object(sc, o, f);
      if (f > 0 && poses_differ(o.poses[f], o.poses[f - 1])) o.moving[f] = 1;
      if (o.first_change == INT_MAX && poses_differ(o.poses[f], o.poses[0])) o.first_change = f;
    }
    if (o.visible_from > 0) o.first_change = std::min(o.first_change, o.visible_from);
    for (int f = 1; f < n;) {
      if (!o.moving[f]) {
        ++f;
        continue;
      }
      int g = f;
      while (g + 1 < n && o.moving[g + 1]) ++g;
      sc.events.push_back({o.id, o.name, "move", f, g});
      f = g + 1;
    }
    if (o.visible_from > 0 && o.visible_from < n)
      sc.events.push_back({o.id, o.name, "appear", o.visible_from, o.visible_from});
    if (o.visible_until < n)
      sc.events.push_back({o.id, o.name, "disappear", o.visible_until, o.visible_until});
  }
  if (sc.light.enabled && sc.light.start < n)
    sc.events.push_back({0, "flashlight", "light", sc.light.start, std::min(sc.light.end, n) - 1});
  for (int f = 1; f < n;) {
    if (sc.exposure[f] == sc.exposure[f - 1]) {
      ++f;
      continue;
    }
    int g = f;
    while (g + 1 < n && sc.exposure[g + 1] != sc.exposure[g]) ++g;
    sc.events.push_back({0, "exposure", "exposure", f, g});
    f = g + 1;
  }
  std::stable_sort(
      sc.events.begin(), sc.events.end(),
      [](const SynthEvent& a, const SynthEvent& b) { return a.first_frame < b.first_frame; });
}

void parse_object(Reader& rd, const YAML::Node& on, SynthScene& sc, TextureTable& tt,
                  std::mt19937_64& rng) {
  rd.known(on, "objects[]",
           {"name", "shape", "size", "texture", "faces", "contrast", "blur_px", "albedo", "xyz",
            "rpy_deg", "pivot", "visible", "moves", "wobble", "variants"});
  SynthObject o;
  o.id = static_cast<int>(sc.objects.size()) + 1;
  o.name = rd.str(on, "name", "object" + std::to_string(o.id));
  const std::string shape = rd.str(on, "shape", "box");
  const double contrast = rd.num(on, "contrast", 1.0, 0.0, 2.0);
  const double blur = rd.num(on, "blur_px", 0.0, 0.0, 20.0);
  const double albedo = rd.num(on, "albedo", 1.0, 0.0, 4.0);
  const std::vector<std::string> texnames = rd.strings(on, "texture", {"box"});
  auto tex = [&](size_t i) { return tt.get(texnames[i % texnames.size()], contrast, blur); };
  if (shape == "box") {
    const Eigen::Vector3d size = rd.vec3(on, "size", {0.5, 0.5, 0.5});
    if ((size.array() <= 0).any()) fail(rd.origin, o.name + ".size: must be positive");
    int t[6];
    for (int i = 0; i < 6; ++i) t[i] = tex(i);
    if (on["faces"]) {
      const YAML::Node fn = on["faces"];
      rd.known(fn, (o.name + ".faces").c_str(),
               {"front", "back", "left", "right", "top", "bottom"});
      const char* names[6] = {"front", "back", "left", "right", "top", "bottom"};
      for (int i = 0; i < 6; ++i)
        if (fn[names[i]]) t[i] = tt.get(fn[names[i]].as<std::string>(), contrast, blur);
    }
    add_box(o.quads, size, Eigen::Vector3d::Zero(), t, albedo);
  } else if (shape == "plane") {
    // Vertical rectangle facing -y, bottom edge at z = 0, centred on x = 0 (a poster, a
    // picture frame); two-sided.
    const Eigen::Vector3d size = rd.vec3(on, "size", {1.0, 0.0, 0.7});
    SynthQuad q =
        quad({-size.x() / 2, 0, size.z()}, {size.x(), 0, 0}, {0, 0, -size.z()}, tex(0), albedo);
    q.two_sided = true;
    o.quads.push_back(q);
  } else if (shape == "person" || shape == "seated_person") {
    // A walking (or seated) person built from boxes: legs, torso, head; about 1.75 m tall.
    // Big, textured and close to the camera, like the people in TUM's walking sequences.
    const double s = rd.num(on, "size", 1.0, 0.3, 3.0);  // scale
    const int body = tex(0);
    const int legs = texnames.size() > 1 ? tex(1) : tt.get("stuff", contrast, blur);
    const int head = texnames.size() > 2 ? tex(2) : tt.get("baboon", contrast, blur);
    const int tb[6] = {body, body, body, body, body, body};
    const int tl[6] = {legs, legs, legs, legs, legs, legs};
    const int th[6] = {head, head, head, head, head, head};
    const double base = shape == "person" ? 0.0 : -0.4;  // seated: legs hidden below the seat
    if (shape == "person")
      add_box(o.quads, s * Eigen::Vector3d(0.36, 0.24, 0.85), {0, 0, 0}, tl, albedo * 0.8);
    add_box(o.quads, s * Eigen::Vector3d(0.50, 0.28, 0.62), {0, 0, s * (0.85 + base)}, tb, albedo);
    add_box(o.quads, s * Eigen::Vector3d(0.20, 0.22, 0.24), {0, 0, s * (1.50 + base)}, th, albedo);
  } else {
    fail(rd.origin,
         o.name + ".shape: '" + shape + "' unknown; allowed box, plane, person, seated_person");
  }
  (void)rng;
  // The pivot becomes the object frame's origin: xyz places it, rotations turn about it.
  const Eigen::Vector3d pivot = rd.vec3(on, "pivot", {0, 0, 0});
  if (!pivot.isZero(0))
    for (auto& q : o.quads) q.p0 -= pivot;
  const Eigen::Vector3d xyz = rd.vec3(on, "xyz", {0, 0, 0});
  Eigen::Vector3d rpy = rd.vec3(on, "rpy_deg", {0, 0, 0});
  o.pose0 = make_pose(xyz, rpy);
  const auto vis = rd.range(on, "visible", {0, INT_MAX});
  o.visible_from = vis.first;
  o.visible_until = vis.second;
  // The motion: the object's own moves and wobble, or the variant the seed picks (seed 1 the
  // first, seed 2 the second, ..., cycling: index (seed - 1) mod N).
  const YAML::Node motion = [&]() -> YAML::Node {
    if (!on["variants"]) return on;
    if (on["moves"] || on["wobble"])
      fail(rd.origin, o.name + ": give either moves/wobble or variants, not both");
    const YAML::Node vs = on["variants"];
    if (!vs.IsSequence() || vs.size() == 0)
      fail(rd.origin, o.name + ".variants: expected a non-empty list");
    const uint64_t n = vs.size();
    const size_t k = static_cast<size_t>((sc.seed % n + n - 1) % n);
    const YAML::Node v = vs[k];
    rd.known(v, (o.name + ".variants[]").c_str(), {"label", "moves", "wobble"});
    o.variant = rd.str(v, "label", "variant " + std::to_string(k + 1));
    return v;
  }();
  if (motion["moves"]) {
    if (!motion["moves"].IsSequence()) fail(rd.origin, o.name + ".moves: expected a list");
    Eigen::Vector3d cur_xyz = xyz, cur_rpy = rpy;
    int last_end = -1;
    for (const auto& mn : motion["moves"]) {
      rd.known(mn, (o.name + ".moves[]").c_str(), {"start", "end", "xyz", "rpy_deg", "ease"});
      SynthMove m;
      m.start = rd.integer(mn, "start", 0, 0, 10000000);
      m.end = rd.integer(mn, "end", m.start + 30, 0, 10000000);
      if (m.end <= m.start || m.start < last_end)
        fail(rd.origin, o.name + ".moves: each move needs start < end, in order");
      cur_xyz = rd.vec3(mn, "xyz", cur_xyz);
      cur_rpy = rd.vec3(mn, "rpy_deg", cur_rpy);
      m.to = make_pose(cur_xyz, cur_rpy);
      const std::string ease = rd.str(mn, "ease", "smooth");
      if (ease != "smooth" && ease != "linear")
        fail(rd.origin, o.name + ".moves.ease: '" + ease + "'; allowed smooth, linear");
      m.linear = ease == "linear";
      last_end = m.end;
      o.moves.push_back(m);
    }
  }
  if (motion["wobble"]) {
    const YAML::Node wn = motion["wobble"];
    rd.known(wn, (o.name + ".wobble").c_str(),
             {"amplitude_m", "amplitude_deg", "period_s", "start", "end", "fade_s"});
    SynthWobble& w = o.wobble;
    w.enabled = true;
    w.amplitude_m = rd.vec3(wn, "amplitude_m", {0, 0, 0});
    const Eigen::Vector3d ad = rd.vec3(wn, "amplitude_deg", {0, 0, 0});
    w.amplitude_rad = {deg2rad(ad.x()), deg2rad(ad.y()), deg2rad(ad.z())};
    w.period_s = rd.num(wn, "period_s", 2.0, 0.05, 1000);
    w.start = rd.integer(wn, "start", 0, 0, 10000000);
    const int end = rd.integer(wn, "end", -1, -1, 10000000);
    w.end = end < 0 ? INT_MAX : end;
    w.fade_s = rd.num(wn, "fade_s", 0.5, 0.0, 100);
  }
  sc.objects.push_back(std::move(o));
}

}  // namespace

std::string synth_texture_dir() {
  const char* env = std::getenv("RDSLAM_TEXTURE_DIR");
  if (env && *env) return env;
  // Installed layout first (Debian package), then the source tree.
  if (file_exists("/usr/share/rdslam/textures/box.png")) return "/usr/share/rdslam/textures";
  return std::string(RDSLAM_SOURCE_DIR) + "/data/textures";
}

SynthScene load_synth_scene_yaml(const std::string& yaml_text, const std::string& origin,
                                 int frames_override, int64_t seed_override) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    fail(origin, std::string("YAML parse error: ") + e.what());
  }
  if (!root.IsMap()) fail(origin, "expected a YAML mapping at top level");
  Reader rd{origin};
  rd.known(root, "scenario",
           {"name", "frames", "fps", "seed", "camera", "render", "room", "trajectory", "light",
            "exposure", "objects", "texture_dir"});
  SynthScene sc;
  sc.name = rd.str(root, "name", origin);
  sc.frame_count = rd.integer(root, "frames", 300, 1, 1000000);
  if (frames_override > 0) sc.frame_count = frames_override;
  sc.fps = rd.num(root, "fps", 30.0, 1.0, 1000.0);
  sc.seed = static_cast<uint64_t>(rd.num(root, "seed", 1, 0, 1e15));
  if (seed_override >= 0) sc.seed = static_cast<uint64_t>(seed_override);

  const YAML::Node cn = root["camera"];
  rd.known(
      cn, "camera",
      {"width", "height", "fx", "fy", "cx", "cy", "model", "k1", "k2", "p1", "p2", "k3", "k4"});
  sc.camera.width = rd.integer(cn, "width", 640, 16, 8192);
  sc.camera.height = rd.integer(cn, "height", 480, 16, 8192);
  sc.camera.fx = rd.num(cn, "fx", 525.0, 1, 1e5);
  sc.camera.fy = rd.num(cn, "fy", 525.0, 1, 1e5);
  sc.camera.cx = rd.num(cn, "cx", (sc.camera.width - 1) / 2.0, -1e4, 1e4);
  sc.camera.cy = rd.num(cn, "cy", (sc.camera.height - 1) / 2.0, -1e4, 1e4);
  // The lens (core/camera.h): the renderer draws it exactly, SLAM gets it as calibration.
  sc.camera.model = rd.str(cn, "model", "pinhole-radtan");
  if (sc.camera.model != "pinhole-radtan" && sc.camera.model != "pinhole-equidistant")
    fail(origin, "camera.model: '" + sc.camera.model +
                     "' is not a model; allowed pinhole-radtan, pinhole-equidistant");
  double* coeffs[] = {&sc.camera.k1, &sc.camera.k2, &sc.camera.p1,
                      &sc.camera.p2, &sc.camera.k3, &sc.camera.k4};
  const char* coeff_keys[] = {"k1", "k2", "p1", "p2", "k3", "k4"};
  for (int i = 0; i < 6; ++i) *coeffs[i] = rd.num(cn, coeff_keys[i], 0.0, -10, 10);
  if (sc.camera.has_distortion()) {
    if (const std::string e = sc.camera.validate(); !e.empty()) fail(origin, e);
  }

  const YAML::Node rn = root["render"];
  rd.known(rn, "render",
           {"noise_sigma", "motion_blur_samples", "shutter", "near_m", "ambient", "diffuse",
            "full_mip_chain"});
  sc.render.noise_sigma = rd.num(rn, "noise_sigma", 2.0, 0.0, 50.0);
  sc.render.motion_blur_samples = rd.integer(rn, "motion_blur_samples", 0, 0, 32);
  sc.render.shutter = rd.num(rn, "shutter", 0.5, 0.0, 1.0);
  sc.render.near_m = rd.num(rn, "near_m", 0.05, 0.001, 10.0);
  sc.render.ambient = rd.num(rn, "ambient", 0.6, 0.0, 2.0);
  sc.render.diffuse = rd.num(rn, "diffuse", 0.4, 0.0, 2.0);
  sc.render.full_mip_chain = rd.boolean(rn, "full_mip_chain", false);

  const YAML::Node tn = root["trajectory"];
  rd.known(tn, "trajectory",
           {"type",
            "center",
            "target",
            "amplitude_m",
            "period_s",
            "radius_m",
            "azimuth_deg",
            "elevation_deg",
            "elevation_amp_deg",
            "azimuth_period_s",
            "elevation_period_s",
            "rpy_amp_deg",
            "speed_m_s",
            "shake",
            "pauses",
            "path",
            "drive_m",
            "turn_deg",
            "turn_rate_deg_s",
            "axis_offset_m"});
  SynthTrajectorySpec& tr = sc.trajectory;
  tr.type = rd.str(tn, "type", "xyz");
  if (tr.type != "xyz" && tr.type != "halfsphere" && tr.type != "rpy" && tr.type != "static" &&
      tr.type != "forward" && tr.type != "path" && tr.type != "turn")
    fail(origin, "trajectory.type: '" + tr.type +
                     "'; allowed xyz, halfsphere, rpy, static, forward, path, turn");
  const bool forward = tr.type == "forward";
  if (tr.type == "path") {
    tr.amplitude_m.setZero();  // no sinusoids unless asked for
    if (!tn || !tn["path"] || !tn["path"].IsSequence() || tn["path"].size() == 0)
      fail(origin, "trajectory.path: expected [[frame, x, y, z], ...] for type path");
    const size_t width = tn["path"][0].IsSequence() ? tn["path"][0].size() : 0;
    for (const auto& k : tn["path"]) {
      if (!k.IsSequence() || k.size() != width || (width != 4 && width != 7))
        fail(origin,
             "trajectory.path: expected [[frame, x, y, z], ...] or [[frame, x, y, z, tx, ty, "
             "tz], ...] (all keys alike)");
      const double f = k[0].as<double>();
      if (!tr.path.empty() && f <= tr.path.back().first)
        fail(origin, "trajectory.path: frames must increase");
      tr.path.emplace_back(
          f, Eigen::Vector3d(k[1].as<double>(), k[2].as<double>(), k[3].as<double>()));
      if (width == 7)
        tr.path_target.emplace_back(k[4].as<double>(), k[5].as<double>(), k[6].as<double>());
    }
  }
  if (forward) {  // a straight drive unless offsets and swings are asked for
    tr.amplitude_m.setZero();
    tr.rpy_amp_deg.setZero();
  }
  tr.center = rd.vec3(tn, "center", tr.center);
  tr.target = rd.vec3(tn, "target", tr.target);
  if (forward && (tr.target - tr.center).norm() < 1e-9)
    fail(origin, "trajectory.target: must differ from center (it sets the direction of travel)");
  tr.speed_m_s = rd.num(tn, "speed_m_s", tr.speed_m_s, 0.0, 1000.0);
  tr.amplitude_m = rd.vec3(tn, "amplitude_m", tr.amplitude_m);
  tr.period_s = rd.vec3(tn, "period_s", tr.period_s);
  if ((tr.period_s.array() <= 0).any()) fail(origin, "trajectory.period_s: must be positive");
  tr.radius_m = rd.num(tn, "radius_m", tr.radius_m, 0.1, 100);
  tr.azimuth_deg = rd.num(tn, "azimuth_deg", tr.azimuth_deg, 0, 90);
  tr.elevation_deg = rd.num(tn, "elevation_deg", tr.elevation_deg, -80, 80);
  tr.elevation_amp_deg = rd.num(tn, "elevation_amp_deg", tr.elevation_amp_deg, 0, 80);
  tr.azimuth_period_s = rd.num(tn, "azimuth_period_s", tr.azimuth_period_s, 0.1, 1000);
  tr.elevation_period_s = rd.num(tn, "elevation_period_s", tr.elevation_period_s, 0.1, 1000);
  tr.rpy_amp_deg = rd.vec3(tn, "rpy_amp_deg", tr.rpy_amp_deg);
  tr.shake = rd.num(tn, "shake", tr.type == "static" ? 0.0 : 1.0, 0.0, 20.0);
  if (tn && tn["drive_m"]) {
    const YAML::Node d = tn["drive_m"];
    if (!d.IsSequence() || d.size() != 2) fail(origin, "trajectory.drive_m: expected [in, out]");
    try {
      tr.drive_m = {d[0].as<double>(), d[1].as<double>()};
    } catch (const YAML::Exception&) {
      fail(origin, "trajectory.drive_m: expected two numbers");
    }
  }
  tr.turn_deg = rd.num(tn, "turn_deg", tr.turn_deg, -3600, 3600);
  tr.turn_rate_deg_s = rd.num(tn, "turn_rate_deg_s", tr.turn_rate_deg_s, 1, 720);
  tr.axis_offset_m = rd.num(tn, "axis_offset_m", tr.axis_offset_m, -2, 2);
  if (tr.type == "turn" && (tr.drive_m.array() < 0).any())
    fail(origin, "trajectory.drive_m: distances must be >= 0");
  if (tn && tn["pauses"]) {
    for (const auto& p : tn["pauses"]) {
      if (!p.IsSequence() || p.size() != 2)
        fail(origin, "trajectory.pauses: expected [[from, to], ...]");
      const int a = p[0].as<int>(), b = p[1].as<int>();
      if (b <= a || a < 0) fail(origin, "trajectory.pauses: each pause needs 0 <= from < to");
      tr.pauses.emplace_back(a, b);
    }
  }

  const YAML::Node ln = root["light"];
  rd.known(ln, "light",
           {"position", "target", "sweep_m", "period_s", "cone_deg", "edge_deg", "intensity",
            "start", "end"});
  if (ln) {
    SynthSpotLight& L = sc.light;
    L.enabled = true;
    L.position = rd.vec3(ln, "position", L.position);
    L.target = rd.vec3(ln, "target", L.target);
    L.sweep_m = rd.vec3(ln, "sweep_m", L.sweep_m);
    L.period_s = rd.num(ln, "period_s", L.period_s, 0.1, 1000);
    L.cone_deg = rd.num(ln, "cone_deg", L.cone_deg, 0.5, 80);
    L.edge_deg = rd.num(ln, "edge_deg", L.edge_deg, 0.0, 45);
    L.intensity = rd.num(ln, "intensity", L.intensity, 0.0, 100);
    L.start = rd.integer(ln, "start", 0, 0, 10000000);
    const int end = rd.integer(ln, "end", -1, -1, 10000000);
    L.end = end < 0 ? INT_MAX : end;
  }
  if (root["exposure"]) {
    for (const auto& k : root["exposure"]) {
      if (!k.IsSequence() || k.size() != 2) fail(origin, "exposure: expected [[frame, gain], ...]");
      const double g = k[1].as<double>();
      if (!(g > 0 && g < 10)) fail(origin, "exposure: gain must be in (0, 10)");
      sc.exposure_keys.emplace_back(k[0].as<int>(), g);
    }
  }

  TextureTable tt{origin, rd.str(root, "texture_dir", synth_texture_dir()), &sc.textures, {}};
  std::mt19937_64 rng(sc.seed * 1000003 + 5);

  // The room is object 1: walls of poster panels, a tiled floor, a ceiling.
  const YAML::Node room = root["room"];
  rd.known(room, "room",
           {"size", "panel", "wall_textures", "floor_texture", "floor_tile_m", "ceiling_texture",
            "ceiling_tile_m", "contrast", "blur_px", "albedo"});
  {
    SynthObject o;
    o.id = 1;
    o.name = "room";
    const Eigen::Vector3d size = rd.vec3(room, "size", {6.0, 5.0, 2.8});
    if ((size.array() <= 0).any()) fail(origin, "room.size: must be positive");
    const double panel = rd.num(room, "panel", 0.9, 0.1, 10);
    const double contrast = rd.num(room, "contrast", 1.0, 0.0, 2.0);
    const double blur = rd.num(room, "blur_px", 0.0, 0.0, 20.0);
    const double albedo = rd.num(room, "albedo", 1.0, 0.0, 4.0);
    std::vector<int> walls;
    for (const auto& n : rd.strings(room, "wall_textures",
                                    {"building", "leuvenA", "home", "fruits", "board", "butterfly",
                                     "smarties", "starry_night"}))
      walls.push_back(tt.get(n, contrast, blur));
    const int floor_t = tt.get(rd.str(room, "floor_texture", "aero1"), contrast, blur);
    const int ceil_t = tt.get(rd.str(room, "ceiling_texture", "home"), contrast * 0.5, blur);
    const double W = size.x(), D = size.y(), H = size.z();
    using V = Eigen::Vector3d;
    add_panels(o.quads, V(-W / 2, D / 2, H), V(1, 0, 0), V(0, 0, -1), W, H, panel, walls, rng,
               albedo);
    add_panels(o.quads, V(W / 2, -D / 2, H), V(-1, 0, 0), V(0, 0, -1), W, H, panel, walls, rng,
               albedo);
    add_panels(o.quads, V(W / 2, D / 2, H), V(0, -1, 0), V(0, 0, -1), D, H, panel, walls, rng,
               albedo);
    add_panels(o.quads, V(-W / 2, -D / 2, H), V(0, 1, 0), V(0, 0, -1), D, H, panel, walls, rng,
               albedo);
    // Floor and ceiling as a grid of tiles (small quads keep near-plane clipping cheap); the
    // floor texture repeats every floor_tile_m metres.
    const double tile = rd.num(room, "floor_tile_m", 1.5, 0.1, 100);
    const size_t first_floor = o.quads.size();
    add_panels(o.quads, V(-W / 2, D / 2, 0), V(1, 0, 0), V(0, -1, 0), W, D, 1.0, {floor_t}, rng,
               albedo);
    for (size_t i = first_floor; i < o.quads.size(); ++i) {
      SynthQuad& q = o.quads[i];
      q.uv0 = {(q.p0.x() + W / 2) / tile, (D / 2 - q.p0.y()) / tile};
      q.uv_scale = {q.u.norm() / tile, q.v.norm() / tile};
      q.albedo = albedo;
    }
    const double ceil_tile = rd.num(room, "ceiling_tile_m", 2.0, 0.1, 1000);
    const size_t first_ceil = o.quads.size();
    add_panels(o.quads, V(-W / 2, -D / 2, H), V(1, 0, 0), V(0, 1, 0), W, D, 1.0, {ceil_t}, rng,
               albedo);
    for (size_t i = first_ceil; i < o.quads.size(); ++i) {
      SynthQuad& q = o.quads[i];
      q.uv0 = {(q.p0.x() + W / 2) / ceil_tile, (q.p0.y() + D / 2) / ceil_tile};
      q.uv_scale = {q.u.norm() / ceil_tile, q.v.norm() / ceil_tile};
      q.albedo = albedo;
    }
    sc.objects.push_back(std::move(o));
  }
  if (root["objects"]) {
    if (!root["objects"].IsSequence()) fail(origin, "objects: expected a list");
    for (const auto& on : root["objects"]) parse_object(rd, on, sc, tt, rng);
  }
  if (sc.objects.size() > 65535) fail(origin, "too many objects (max 65535)");
  derive(sc);
  return sc;
}

SynthScene load_synth_scene(const std::string& scenario_or_yaml, int frames_override,
                            int64_t seed_override) {
  const std::string builtin = synth_scenario_yaml(scenario_or_yaml);
  if (!builtin.empty())
    return load_synth_scene_yaml(builtin, scenario_or_yaml, frames_override, seed_override);
  if (!file_exists(scenario_or_yaml)) {
    std::string names;
    for (const auto& n : synth_scenario_names()) names += (names.empty() ? "" : ", ") + n;
    throw std::runtime_error("synth: '" + scenario_or_yaml + "' is neither a scenario (" + names +
                             ") nor a YAML file");
  }
  std::ifstream in(scenario_or_yaml);
  std::stringstream ss;
  ss << in.rdbuf();
  return load_synth_scene_yaml(ss.str(), scenario_or_yaml, frames_override, seed_override);
}

// ---- queries ----

Eigen::Isometry3d SynthScene::camera_pose(double frame) const {
  const int f = static_cast<int>(std::floor(frame));
  if (frame == f && f >= 0 && f < static_cast<int>(T_world_cam.size())) return T_world_cam[f];
  const Shake shake(seed, trajectory.shake);
  return eval_camera(*this, shake, frame);
}

const SynthObject* SynthScene::object(int id) const {
  if (id < 1 || id > static_cast<int>(objects.size())) return nullptr;
  return &objects[id - 1];
}

const SynthObject* SynthScene::object(const std::string& n) const {
  for (const auto& o : objects)
    if (o.name == n) return &o;
  return nullptr;
}

Eigen::Isometry3d SynthScene::object_pose(int id, double frame) const {
  const SynthObject* o = object(id);
  if (!o) return Eigen::Isometry3d::Identity();
  const int f = static_cast<int>(std::floor(frame));
  if (frame == f && f >= 0 && f < static_cast<int>(o->poses.size())) return o->poses[f];
  return eval_object(*this, *o, frame);
}

bool SynthScene::object_visible(int id, int frame) const {
  const SynthObject* o = object(id);
  return o && frame >= o->visible_from && frame < o->visible_until;
}

bool SynthScene::object_dynamic(int id, int frame) const {
  const SynthObject* o = object(id);
  return o && object_visible(id, frame) && frame >= o->first_change;
}

bool SynthScene::moved_between(int id, int a, int b) const {
  if (object_visible(id, a) != object_visible(id, b)) return true;
  return poses_differ(object_pose(id, a), object_pose(id, b));
}

bool SynthScene::light_on(int frame) const {
  return light.enabled && frame >= light.start && frame < light.end;
}

Eigen::Vector3d SynthScene::light_aim(double frame) const {
  const double t = (frame - light.start) / fps;
  const double ph = 2 * kPi * t / light.period_s;
  const Eigen::Vector3d aim =
      light.target + Eigen::Vector3d(light.sweep_m.x() * std::sin(ph),
                                     light.sweep_m.y() * std::sin(0.5 * ph),
                                     light.sweep_m.z() * std::sin(1.7 * ph + 0.5));
  return (aim - light.position).normalized();
}

namespace {
// Plane-local coordinates of X (object frame) on quad q: returns false when outside.
bool quad_local(const SynthQuad& q, const Eigen::Vector3d& X, double* s, double* t) {
  const Eigen::Vector3d n = q.v.cross(q.u);
  const Eigen::Vector3d as = q.v.cross(n) / q.u.dot(q.v.cross(n));
  const Eigen::Vector3d at = n.cross(q.u) / q.v.dot(n.cross(q.u));
  *s = as.dot(X - q.p0);
  *t = at.dot(X - q.p0);
  return *s >= 0 && *s <= 1 && *t >= 0 && *t <= 1;
}
}  // namespace

SynthSurfaceHit SynthScene::surface_at(const Eigen::Vector3d& p_world, int frame,
                                       double tol_m) const {
  SynthSurfaceHit best;
  double best_d = tol_m;
  for (const auto& o : objects) {
    if (!object_visible(o.id, frame)) continue;
    const Eigen::Vector3d X = object_pose(o.id, frame).inverse() * p_world;
    for (size_t i = 0; i < o.quads.size(); ++i) {
      const SynthQuad& q = o.quads[i];
      const Eigen::Vector3d n = q.v.cross(q.u).normalized();
      const double d = std::abs(n.dot(X - q.p0));
      double s, t;
      if (d <= best_d && quad_local(q, X, &s, &t)) {
        best_d = d;
        best.object_id = o.id;
        best.quad = static_cast<int>(i);
        best.p_obj = X;
      }
    }
  }
  return best;
}

int SynthScene::raycast(int frame, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                        double* lambda_out) const {
  int best_id = 0;
  double best = std::numeric_limits<double>::infinity();
  for (const auto& o : objects) {
    if (!object_visible(o.id, frame)) continue;
    const Eigen::Isometry3d T_obj_world = object_pose(o.id, frame).inverse();
    const Eigen::Vector3d oo = T_obj_world * origin;
    const Eigen::Vector3d dd = T_obj_world.linear() * dir;
    for (const auto& q : o.quads) {
      const Eigen::Vector3d n = q.v.cross(q.u);
      // Same visibility rule as the renderer: one-sided quads are seen from their front only.
      if (!q.two_sided && n.dot(oo - q.p0) <= 0) continue;
      const double den = n.dot(dd);
      if (std::abs(den) < 1e-15) continue;
      const double lambda = n.dot(q.p0 - oo) / den;
      if (lambda <= 1e-12 || lambda >= best) continue;
      double s, t;
      if (!quad_local(q, oo + lambda * dd, &s, &t)) continue;
      best = lambda;
      best_id = o.id;
    }
  }
  if (lambda_out) *lambda_out = best;
  return best_id;
}

SynthPointFate SynthScene::point_fate(const Eigen::Vector3d& p_world, int frame_ref, int frame,
                                      double tol_m) const {
  SynthPointFate r;
  const SynthSurfaceHit hit = surface_at(p_world, frame_ref, tol_m);
  r.object_id = hit.object_id;
  r.p_world_now = p_world;
  if (hit.object_id != 0) {
    if (!object_visible(hit.object_id, frame)) {
      r.moved = true;
    } else {
      r.p_world_now = object_pose(hit.object_id, frame) * hit.p_obj;
      r.moved = (r.p_world_now - p_world).norm() > tol_m;
    }
  }
  const Eigen::Isometry3d T_cam_world = camera_pose(frame).inverse();
  const Eigen::Vector3d pc = T_cam_world * p_world;
  if (pc.z() > render.near_m) {
    Eigen::Vector2d uv(camera.fx * pc.x() / pc.z() + camera.cx,
                       camera.fy * pc.y() / pc.z() + camera.cy);
    if (camera.has_distortion()) uv = camera.distort(uv);
    r.in_view = uv.x() >= -0.5 && uv.y() >= -0.5 && uv.x() < camera.width - 0.5 &&
                uv.y() < camera.height - 0.5;
  }
  const Eigen::Vector3d c = camera_pose(frame).translation();
  const Eigen::Vector3d d = p_world - c;
  double lambda = 0;
  const int id = raycast(frame, c, d, &lambda);
  // Something lies in front of the point's old position by more than the tolerance.
  if (id != 0 && (1.0 - lambda) * d.norm() > tol_m) {
    r.occluded = true;
    r.occluder_id = id;
  }
  return r;
}

}  // namespace rdslam
