// `rdslam view [--listen 127.0.0.1:8080] [--token T]`: a separate, read-only process that
// subscribes to rdslam's LCM channels (lcm.pose_channel, status_channel, image_channel,
// map_channel of the configuration) and serves one page to a browser (firmware_app/
// view_page.h): the live annotated image, a 3D view of the trajectory, keyframes and map
// points, and the tracking state, frame, fps, latency and drop counters (docs/viewer.md).
//
// It never talks to the rdslam process: it only listens to LCM's UDP multicast, so running,
// stalling or crashing it cannot slow the pipeline (measured in docs/viewer.md).
//
// HTTP: a small GET-only HTTP/1.1 server on one thread (four paths: /, /api/state,
// /api/map, /api/image.jpg; every response closes the connection; requests larger than
// 8 KiB or slower than 2 s are dropped). Written here rather than taken from a library so
// that the robot needs no extra shared library and the aarch64 cross build is unchanged.
// Security: binds to 127.0.0.1 unless told otherwise; a non-loopback address needs
// --token, and then every request must carry it (?token= or "Authorization: Bearer");
// without a token, requests must name a loopback Host (no DNS rebinding). No request changes
// anything.
//
// Threads: main (supervision, signals), the LCM receive thread, the HTTP thread; the shared
// view state is guarded by one mutex held only for copies.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "bot_core/image_t.hpp"
#include "core/log.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"
#include "firmware_app/pipeline.h"
#include "firmware_app/view_page.h"
#include "rdslam/map_t.hpp"
#include "rdslam/pose_t.hpp"
#include "rdslam/status_t.hpp"

namespace rdslam {

namespace {

const char* state_name(int s) {
  switch (s) {
    case ::rdslam::pose_t::STATE_INITIALIZING:
      return "INITIALIZING";
    case ::rdslam::pose_t::STATE_TRACKING:
      return "TRACKING";
    case ::rdslam::pose_t::STATE_LOST:
      return "LOST";
    case ::rdslam::pose_t::STATE_RELOCALIZED:
      return "RELOCALIZED";
    default:
      return "UNKNOWN";
  }
}

void append(std::string& out, const char* fmt, ...) __attribute__((format(printf, 2, 3)));
void append(std::string& out, const char* fmt, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, fmt);
  const int n = std::vsnprintf(buf, sizeof(buf), fmt, ap);
  va_end(ap);
  if (n > 0) out.append(buf, static_cast<size_t>(std::min<int>(n, sizeof(buf) - 1)));
}

// A finite number as JSON (NaN/inf: null).
void append_num(std::string& out, double v, const char* fmt = "%.6g") {
  if (std::isfinite(v)) {
    append(out, fmt, v);
  } else {
    out += "null";
  }
}

// Trajectory points kept at most; beyond, every other point is dropped (a new generation).
constexpr size_t kMaxTrajectory = 200000;

// Everything the page shows; written by the LCM thread, read by the HTTP thread.
class ViewState {
 public:
  explicit ViewState(std::string url) : url_(std::move(url)) {}

  void on_pose(const ::rdslam::pose_t& m) {
    std::lock_guard<std::mutex> lk(mu_);
    touch();
    ++poses_;
    pose_ = m;
    have_pose_ = true;
    recent_[recent_next_++ % kRecent] = {m.utime, m.seq};
    if (m.map_epoch != traj_epoch_) {  // a new map: a new world frame
      traj_.clear();
      traj_epoch_ = m.map_epoch;
      ++traj_gen_;
    }
    if (m.state == ::rdslam::pose_t::STATE_TRACKING ||
        m.state == ::rdslam::pose_t::STATE_RELOCALIZED) {
      if (traj_.size() / 3 >= kMaxTrajectory) {
        size_t w = 0;
        for (size_t i = 0; i < traj_.size(); i += 6, w += 3) {
          for (int k = 0; k < 3; ++k) traj_[w + k] = traj_[i + k];
        }
        traj_.resize(w);
        ++traj_gen_;
      }
      for (int k = 0; k < 3; ++k) traj_.push_back(static_cast<float>(m.position[k]));
    }
  }
  void on_status(const ::rdslam::status_t& m) {
    std::lock_guard<std::mutex> lk(mu_);
    touch();
    ++statuses_;
    status_ = m;
    have_status_ = true;
  }
  void on_image(const bot_core::image_t& m) {
    std::lock_guard<std::mutex> lk(mu_);
    touch();
    if (m.pixelformat != bot_core::image_t::PIXEL_FORMAT_MJPEG) {
      ++ignored_;
      return;
    }
    jpeg_.assign(m.data.begin(), m.data.end());
    ++image_seq_;
    image_utime_ = m.utime;
    image_frame_ = -1;  // the frame of the image: the pose with its stamp
    for (const auto& r : recent_) {
      if (r.first == m.utime) image_frame_ = r.second;
    }
  }
  void on_map(const ::rdslam::map_t& m) {
    std::string j;
    j.reserve(64 + static_cast<size_t>(m.num_points) * 30 +
              static_cast<size_t>(m.num_keyframes) * 40);
    {
      std::lock_guard<std::mutex> lk(mu_);
      append(j, "{\"version\":%lld,", static_cast<long long>(map_version_ + 1));
    }
    append(j, "\"seq\":%lld,\"epoch\":%lld,\"total_points\":%d,\"kf\":[",
           static_cast<long long>(m.seq), static_cast<long long>(m.map_epoch), m.total_points);
    for (int k = 0; k < m.num_keyframes; ++k) {
      for (int c = 0; c < 3; ++c) {
        if (k || c) j += ',';
        append_num(j, m.keyframe_position[static_cast<size_t>(k)][static_cast<size_t>(c)], "%.4g");
      }
    }
    j += "],\"pts\":[";
    for (int i = 0; i < m.num_points; ++i) {
      for (int c = 0; c < 3; ++c) {
        if (i || c) j += ',';
        append_num(j, m.point_position[static_cast<size_t>(i)][static_cast<size_t>(c)], "%.4g");
      }
    }
    j += "],\"valid\":[";
    for (int i = 0; i < m.num_points; ++i) {
      if (i) j += ',';
      j += m.point_valid[static_cast<size_t>(i)] ? '1' : '0';
    }
    j += "]}";
    std::lock_guard<std::mutex> lk(mu_);
    touch();
    ++map_version_;
    map_json_.swap(j);
  }
  void on_decode_error() {
    std::lock_guard<std::mutex> lk(mu_);
    ++decode_errors_;
  }

  // /api/state: trajectory points from index `from` when `gen` is the current generation,
  // else from 0.
  std::string state_json(size_t from, long long gen) {
    std::string j;
    std::lock_guard<std::mutex> lk(mu_);
    if (gen != traj_gen_) from = 0;
    from = std::min(from, traj_.size() / 3);
    append(j, "{\"lcm_url\":\"%s\",\"traj_gen\":%lld,\"traj_from\":%zu,\"traj_total\":%zu,",
           json_safe(url_).c_str(), traj_gen_, from, traj_.size() / 3);
    j += "\"traj\":[";
    for (size_t i = from * 3; i < traj_.size(); ++i) {
      if (i > from * 3) j += ',';
      append_num(j, traj_[i], "%.5g");
    }
    j += "],";
    append(j,
           "\"messages\":{\"poses\":%llu,\"statuses\":%llu,\"images\":%llu,\"maps\":%llu,"
           "\"decode_errors\":%llu,\"ignored\":%llu},",
           static_cast<unsigned long long>(poses_), static_cast<unsigned long long>(statuses_),
           static_cast<unsigned long long>(image_seq_ + 1),
           static_cast<unsigned long long>(map_version_ + 1),
           static_cast<unsigned long long>(decode_errors_),
           static_cast<unsigned long long>(ignored_));
    j += "\"last_message_age_s\":";
    if (last_msg_ns_ > 0) {
      append_num(j, (mono_now_ns() - last_msg_ns_) * 1e-9, "%.2f");
    } else {
      j += "null";
    }
    append(j, ",\"image_seq\":%lld,\"image_frame\":%lld,\"map_version\":%lld,", image_seq_,
           static_cast<long long>(image_frame_), map_version_);
    j += "\"pose\":";
    if (have_pose_) {
      const ::rdslam::pose_t& p = pose_;
      append(j, "{\"seq\":%lld,\"utime\":%lld,\"map_epoch\":%lld,\"state\":\"%s\",\"inliers\":%d,",
             static_cast<long long>(p.seq), static_cast<long long>(p.utime),
             static_cast<long long>(p.map_epoch), state_name(p.state), p.inliers);
      j += "\"quality\":";
      append_num(j, p.quality);
      j += ",\"latency_ms\":";
      append_num(j, p.latency_us * 1e-3, "%.3f");
      j += ",\"position\":[";
      for (int k = 0; k < 3; ++k) {
        if (k) j += ',';
        append_num(j, p.position[k]);
      }
      j += "]}";
    } else {
      j += "null";
    }
    j += ",\"status\":";
    if (have_status_) {
      const ::rdslam::status_t& s = status_;
      j += "{\"fps\":";
      append_num(j, s.fps, "%.2f");
      j += ",\"latency_p50_ms\":";
      append_num(j, s.latency_p50_ms, "%.3f");
      j += ",\"latency_p99_ms\":";
      append_num(j, s.latency_p99_ms, "%.3f");
      j += ",\"tracker_p50_ms\":";
      append_num(j, s.tracker_p50_ms, "%.3f");
      j += ",\"tracker_p99_ms\":";
      append_num(j, s.tracker_p99_ms, "%.3f");
      append(
          j,
          ",\"frames_captured\":%lld,\"frames_processed\":%lld,\"frames_dropped\":%lld,"
          "\"source_faults\":%lld,\"map_points\":%d,\"keyframes\":%d,\"invalidated_points\":%lld}",
          static_cast<long long>(s.frames_captured), static_cast<long long>(s.frames_processed),
          static_cast<long long>(s.frames_dropped), static_cast<long long>(s.source_faults),
          s.map_points, s.keyframes, static_cast<long long>(s.invalidated_points));
    } else {
      j += "null";
    }
    j += "}";
    return j;
  }
  bool image(std::string& out) {
    std::lock_guard<std::mutex> lk(mu_);
    if (image_seq_ < 0) return false;
    out = jpeg_;
    return true;
  }
  bool map(std::string& out) {
    std::lock_guard<std::mutex> lk(mu_);
    if (map_version_ < 0) return false;
    out = map_json_;
    return true;
  }

 private:
  void touch() { last_msg_ns_ = mono_now_ns(); }
  static std::string json_safe(const std::string& s) {
    std::string o;
    for (char c : s) {
      if (c == '"' || c == '\\') o += '\\';
      if (static_cast<unsigned char>(c) >= 0x20) o += c;
    }
    return o;
  }

  const std::string url_;
  std::mutex mu_;
  int64_t last_msg_ns_ = 0;
  uint64_t poses_ = 0, statuses_ = 0, decode_errors_ = 0, ignored_ = 0;
  ::rdslam::pose_t pose_{};
  bool have_pose_ = false;
  static constexpr size_t kRecent = 256;  // (utime, seq) of the last poses
  std::pair<int64_t, int64_t> recent_[kRecent] = {};
  size_t recent_next_ = 0;
  ::rdslam::status_t status_{};
  bool have_status_ = false;
  std::vector<float> traj_;
  int64_t traj_epoch_ = -1;
  long long traj_gen_ = 0;
  std::string jpeg_;
  long long image_seq_ = -1;
  int64_t image_utime_ = 0, image_frame_ = -1;
  std::string map_json_;
  long long map_version_ = -1;
};

// Decodes raw LCM messages (a version mismatch is counted, not fatal).
template <typename T, typename F>
void subscribe(lcm::LCM& lc, const std::string& channel, ViewState& st, F on) {
  lc.subscribeFunction(
      channel,
      +[](const lcm::ReceiveBuffer* rb, const std::string&, std::pair<ViewState*, F>* ctx) {
        T m;
        if (m.decode(rb->data, 0, static_cast<int>(rb->data_size)) < 0) {
          ctx->first->on_decode_error();
          return;
        }
        ctx->second(*ctx->first, m);
      },
      new std::pair<ViewState*, F>(&st, on));  // lives as long as the process
}

struct Listen {
  in_addr addr{};
  int port = 8080;
  bool loopback = true;
};

Listen parse_listen(const std::string& s) {
  const size_t colon = s.rfind(':');
  if (colon == std::string::npos)
    throw UsageError("--listen: expected ADDRESS:PORT, got '" + s + "'");
  std::string host = s.substr(0, colon);
  const std::string port = s.substr(colon + 1);
  Listen l;
  char* end = nullptr;
  const long p = std::strtol(port.c_str(), &end, 10);
  if (port.empty() || *end != '\0' || p < 0 || p > 65535) {
    throw UsageError("--listen: port '" + port + "' is not in 0..65535");
  }
  l.port = static_cast<int>(p);
  if (host == "localhost") host = "127.0.0.1";
  if (inet_pton(AF_INET, host.c_str(), &l.addr) != 1) {
    throw UsageError("--listen: '" + host + "' is not an IPv4 address (e.g. 127.0.0.1, 0.0.0.0)");
  }
  l.loopback = (ntohl(l.addr.s_addr) >> 24) == 127;
  return l;
}

bool equal_const_time(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char d = 0;
  for (size_t i = 0; i < a.size(); ++i) d |= static_cast<unsigned char>(a[i] ^ b[i]);
  return d == 0;
}

std::string query_param(const std::string& query, const std::string& key) {
  size_t pos = 0;
  while (pos <= query.size()) {
    size_t amp = query.find('&', pos);
    if (amp == std::string::npos) amp = query.size();
    const std::string kv = query.substr(pos, amp - pos);
    const size_t eq = kv.find('=');
    if (kv.substr(0, eq) == key) {
      std::string v = eq == std::string::npos ? "" : kv.substr(eq + 1);
      std::string out;  // percent-decoding
      for (size_t i = 0; i < v.size(); ++i) {
        if (v[i] == '%' && i + 2 < v.size() + 0 &&
            std::isxdigit(static_cast<unsigned char>(v[i + 1])) &&
            std::isxdigit(static_cast<unsigned char>(v[i + 2]))) {
          out += static_cast<char>(std::stoi(v.substr(i + 1, 2), nullptr, 16));
          i += 2;
        } else {
          out += v[i] == '+' ? ' ' : v[i];
        }
      }
      return out;
    }
    pos = amp + 1;
  }
  return {};
}

// The value of header `name` (case-insensitive) in `head`, or "".
std::string header_value(const std::string& head, const char* name) {
  const size_t n = std::strlen(name);
  size_t pos = head.find("\r\n");
  while (pos != std::string::npos && pos + 2 < head.size()) {
    const size_t start = pos + 2;
    const size_t end = head.find("\r\n", start);
    const std::string line =
        head.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (line.size() > n && line[n] == ':' && strncasecmp(line.c_str(), name, n) == 0) {
      size_t v = n + 1;
      while (v < line.size() && line[v] == ' ') ++v;
      return line.substr(v);
    }
    pos = end;
  }
  return {};
}

class HttpServer {
 public:
  HttpServer(const Listen& l, std::string token, ViewState& state)
      : token_(std::move(token)), state_(state) {
    fd_ = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error(std::string("view: socket: ") + std::strerror(errno));
    const int one = 1;
    setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(l.port));
    a.sin_addr = l.addr;
    if (bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0 || listen(fd_, 16) != 0) {
      const std::string e = std::strerror(errno);
      close(fd_);
      throw std::runtime_error("view: cannot listen on " + address(l.addr) + ":" +
                               std::to_string(l.port) + ": " + e);
    }
    socklen_t len = sizeof(a);
    getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
  }
  ~HttpServer() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
    if (fd_ >= 0) close(fd_);
  }
  int port() const { return port_; }
  uint64_t requests() const { return requests_.load(); }
  void start() {
    thread_ = std::thread([this] { loop(); });
  }
  static std::string address(in_addr a) {
    char buf[INET_ADDRSTRLEN] = {0};
    inet_ntop(AF_INET, &a, buf, sizeof(buf));
    return buf;
  }

 private:
  void loop() {
    while (!stop_.load()) {
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 200) <= 0) continue;
      const int c = accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (c < 0) continue;
      timeval tv{2, 0};
      setsockopt(c, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
      setsockopt(c, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof(tv));
      handle(c);
      close(c);
    }
  }

  void handle(int c) {
    std::string head;
    char buf[2048];
    while (head.find("\r\n\r\n") == std::string::npos) {
      if (head.size() > 8192) return reply(c, 431, "text/plain", "request too large\n");
      const ssize_t n = recv(c, buf, sizeof(buf), 0);
      if (n <= 0) return;
      head.append(buf, static_cast<size_t>(n));
    }
    requests_.fetch_add(1);
    const size_t sp1 = head.find(' ');
    const size_t sp2 = sp1 == std::string::npos ? sp1 : head.find(' ', sp1 + 1);
    if (sp2 == std::string::npos) return reply(c, 400, "text/plain", "bad request\n");
    const std::string method = head.substr(0, sp1);
    const std::string target = head.substr(sp1 + 1, sp2 - sp1 - 1);
    if (method != "GET" && method != "HEAD") {
      return reply(c, 405, "text/plain", "read-only: GET only\n", method == "HEAD");
    }
    const bool head_only = method == "HEAD";
    const size_t q = target.find('?');
    const std::string path = target.substr(0, q);
    const std::string query = q == std::string::npos ? "" : target.substr(q + 1);
    if (!token_.empty()) {
      std::string given = query_param(query, "token");
      const std::string auth = header_value(head, "Authorization");
      if (given.empty() && auth.rfind("Bearer ", 0) == 0) given = auth.substr(7);
      if (!equal_const_time(given, token_)) {
        return reply(c, 401, "text/plain", "token required (?token=... or Authorization: Bearer)\n",
                     head_only);
      }
    } else if (!loopback_host(header_value(head, "Host"))) {
      return reply(c, 403, "text/plain", "Host must be a loopback address\n", head_only);
    }
    if (path == "/" || path == "/index.html") {
      return reply(c, 200, "text/html; charset=utf-8", view_page_html(), head_only);
    }
    if (path == "/api/state") {
      const std::string from = query_param(query, "traj_from");
      const std::string gen = query_param(query, "gen");
      return reply(c, 200, "application/json",
                   state_.state_json(static_cast<size_t>(std::strtoull(from.c_str(), nullptr, 10)),
                                     std::strtoll(gen.c_str(), nullptr, 10)),
                   head_only);
    }
    std::string body;
    if (path == "/api/map") {
      if (!state_.map(body)) return reply(c, 404, "text/plain", "no map yet\n", head_only);
      return reply(c, 200, "application/json", body, head_only);
    }
    if (path == "/api/image.jpg") {
      if (!state_.image(body)) return reply(c, 404, "text/plain", "no image yet\n", head_only);
      return reply(c, 200, "image/jpeg", body, head_only);
    }
    return reply(c, 404, "text/plain", "not found\n", head_only);
  }

  static bool loopback_host(const std::string& host) {
    std::string h = host;
    if (!h.empty() && h[0] == '[') {
      return h.rfind("[::1]", 0) == 0;
    }
    const size_t colon = h.find(':');
    if (colon != std::string::npos) h = h.substr(0, colon);
    if (h == "localhost") return true;
    in_addr a{};
    return inet_pton(AF_INET, h.c_str(), &a) == 1 && (ntohl(a.s_addr) >> 24) == 127;
  }

  static void reply(int c, int code, const char* type, const std::string& body,
                    bool head_only = false) {
    const char* reason = code == 200   ? "OK"
                         : code == 400 ? "Bad Request"
                         : code == 401 ? "Unauthorized"
                         : code == 403 ? "Forbidden"
                         : code == 404 ? "Not Found"
                         : code == 405 ? "Method Not Allowed"
                                       : "Request Header Fields Too Large";
    std::string h;
    append(h,
           "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\nConnection: close\r\n"
           "Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n"
           "Content-Security-Policy: default-src 'self'; script-src 'self' 'unsafe-inline'; "
           "style-src 'self' 'unsafe-inline'; img-src 'self'; connect-src 'self'\r\n",
           code, reason, type, body.size());
    if (code == 405) h += "Allow: GET, HEAD\r\n";
    h += "\r\n";
    if (!head_only) h += body;
    size_t off = 0;
    while (off < h.size()) {
      const ssize_t n = send(c, h.data() + off, h.size() - off, MSG_NOSIGNAL);
      if (n <= 0) return;
      off += static_cast<size_t>(n);
    }
  }

  int fd_ = -1;
  int port_ = 0;
  const std::string token_;
  ViewState& state_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> requests_{0};
  std::thread thread_;
};

}  // namespace

int cmd_view(int argc, char** argv) {
  std::string config_path, listen = "127.0.0.1:8080", token;
  std::vector<std::string> overrides;
  ArgParser p("rdslam view [--listen ADDRESS:PORT] [--token T] [--config FILE] [--set K=V ...]",
              "Serve a live web view of a running rdslam (rdslam run, or rdslam replay --lcm) to\n"
              "a browser: the annotated camera image, a 3D view of the trajectory, keyframes\n"
              "and map points (drag: orbit, wheel: zoom), tracking state, frame, fps, latency\n"
              "and drop counters. A separate read-only process: it subscribes to the LCM\n"
              "channels of the configuration (lcm.url, lcm.*_channel) and never talks to rdslam.\n"
              "Prints the page's URL on stdout; runs until SIGINT or SIGTERM.");
  p.option("--listen", &listen, "ADDRESS:PORT",
           "IPv4 address and port to serve on (default 127.0.0.1:8080; port 0: any free port)");
  p.option("--token", &token, "T",
           "required with a non-loopback address: every request must carry it (the page's URL "
           "?token=T, or the header Authorization: Bearer T)");
  p.config_options(&config_path, &overrides);
  if (!p.parse(argc, argv)) return 0;
  const Listen l = parse_listen(listen);
  if (!l.loopback && token.empty()) {
    throw UsageError("--listen " + listen +
                     ": not a loopback address; give --token T (every request must carry it) "
                     "or listen on 127.0.0.1");
  }
  for (char ch : token) {
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '-' && ch != '_' && ch != '.') {
      throw UsageError("--token: use letters, digits, '-', '_' and '.' only");
    }
  }
  const AppConfig cfg = load_cli_config(config_path, overrides);

  // Before any thread exists, so that every thread inherits the mask (as rdslam run).
  sigset_t set, old;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &set, &old);

  lcm::LCM lc(cfg.lcm.url);
  if (!lc.good()) throw std::runtime_error("lcm: cannot open provider URL '" + cfg.lcm.url + "'");
  ViewState state(cfg.lcm.url);
  subscribe<::rdslam::pose_t>(lc, cfg.lcm.pose_channel, state,
                              [](ViewState& s, const ::rdslam::pose_t& m) { s.on_pose(m); });
  subscribe<::rdslam::status_t>(lc, cfg.lcm.status_channel, state,
                                [](ViewState& s, const ::rdslam::status_t& m) { s.on_status(m); });
  subscribe<bot_core::image_t>(lc, cfg.lcm.image_channel, state,
                               [](ViewState& s, const bot_core::image_t& m) { s.on_image(m); });
  subscribe<::rdslam::map_t>(lc, cfg.lcm.map_channel, state,
                             [](ViewState& s, const ::rdslam::map_t& m) { s.on_map(m); });

  HttpServer server(l, token, state);
  std::atomic<bool> stop{false};
  std::thread receiver([&] {
    while (!stop.load()) lc.handleTimeout(100);
  });
  server.start();
  const std::string host =
      HttpServer::address(l.addr) == "0.0.0.0" ? "127.0.0.1" : HttpServer::address(l.addr);
  std::printf("rdslam view: http://%s:%d/%s\n", host.c_str(), server.port(),
              token.empty() ? "" : ("?token=" + token).c_str());
  std::fflush(stdout);
  RDSLAM_LOG_INFO("view: listening on %s:%d, LCM %s (%s, %s, %s, %s)",
                  HttpServer::address(l.addr).c_str(), server.port(), cfg.lcm.url.c_str(),
                  cfg.lcm.pose_channel.c_str(), cfg.lcm.status_channel.c_str(),
                  cfg.lcm.image_channel.c_str(), cfg.lcm.map_channel.c_str());
  for (;;) {
    timespec ts{1, 0};
    const int sig = sigtimedwait(&set, nullptr, &ts);
    if (sig == SIGINT || sig == SIGTERM) break;
  }
  stop.store(true);
  receiver.join();
  RDSLAM_LOG_INFO("view: stopped after %llu requests",
                  static_cast<unsigned long long>(server.requests()));
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  return 0;
}

}  // namespace rdslam
