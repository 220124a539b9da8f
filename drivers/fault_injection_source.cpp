#include "drivers/fault_injection_source.h"

#include <cerrno>
#include <cstdlib>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <utility>

#include "drivers/mjpeg_decoder.h"

namespace rdslam {

namespace {

struct KindName {
  FaultKind kind;
  const char* name;
};
constexpr KindName kKinds[] = {
    {FaultKind::kCorrupt, "corrupt"},
    {FaultKind::kTruncate, "truncate"},
    {FaultKind::kZero, "zero"},
    {FaultKind::kBlack, "black"},
    {FaultKind::kSaturated, "saturated"},
    {FaultKind::kExposure, "exposure"},
    {FaultKind::kStampBack, "stamp_back"},
    {FaultKind::kDupStamp, "dup_stamp"},
    {FaultKind::kDrop, "drop"},
    {FaultKind::kUnplug, "unplug"},
};

[[noreturn]] void bad_item(const std::string& item, const std::string& why) {
  throw std::invalid_argument("--inject: '" + item + "': " + why +
                              " (KIND@FIRST[-LAST][:VALUE], KIND one of corrupt, truncate, zero, "
                              "black, saturated, exposure, stamp_back, dup_stamp, drop, unplug)");
}

int64_t parse_frame(const std::string& item, const std::string& text) {
  if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos ||
      text.size() > 12) {
    bad_item(item, "frame number '" + text + "' is not an integer in 0..999999999999");
  }
  return std::stoll(text);
}

class FaultInjectionSource final : public FrameSource {
 public:
  FaultInjectionSource(std::unique_ptr<FrameSource> inner, std::vector<FaultSpan> plan)
      : inner_(std::move(inner)), plan_(std::move(plan)), info_(inner_->info()) {
    info_.uri += " (fault injection)";
  }

  SourceStatus read(Frame& out, int timeout_ms) override {
    for (;;) {
      const SourceStatus s = inner_->read(out, timeout_ms);
      if (s != SourceStatus::kOk) return s;
      const int64_t n = next_frame_++;
      const FaultSpan* unplug = find(FaultKind::kUnplug, n);
      if (unplugged_ && !unplug) {
        unplugged_ = false;
        ++reopens_;  // the camera is back: this frame is delivered
      }
      if (unplug) {
        if (!unplugged_) {
          unplugged_ = true;
          ++faults_;
          return SourceStatus::kFault;  // the read that found the device gone
        }
        return SourceStatus::kTimeout;
      }
      if (find(FaultKind::kDrop, n)) {
        ++skipped_;
        continue;
      }
      return damage(out, n);
    }
  }

  const SourceInfo& info() const override { return info_; }
  std::optional<CameraModel> camera() const override { return inner_->camera(); }
  std::optional<Trajectory> ground_truth() const override { return inner_->ground_truth(); }
  SourceCounters counters() const override {
    SourceCounters c = inner_->counters();
    c.skipped += skipped_;
    c.reopens += reopens_;
    c.faults += faults_;
    c.delivered = delivered_;
    return c;
  }

 private:
  const FaultSpan* find(FaultKind k, int64_t n) const {
    for (const FaultSpan& f : plan_) {
      if (f.kind == k && n >= f.first && n <= f.last) return &f;
    }
    return nullptr;
  }

  SourceStatus damage(Frame& out, int64_t n) {
    const int64_t good_stamp = out.stamp_ns;
    if (find(FaultKind::kStampBack, n) && have_stamp_) {
      out.stamp_ns = last_stamp_ns_ - (last_interval_ns_ > 0 ? last_interval_ns_ : 1000000);
    } else if (find(FaultKind::kDupStamp, n) && have_stamp_) {
      out.stamp_ns = last_stamp_ns_;
    } else {
      if (have_stamp_) last_interval_ns_ = good_stamp - last_stamp_ns_;
      last_stamp_ns_ = good_stamp;
      have_stamp_ = true;
    }
    if (const FaultSpan* e = find(FaultKind::kExposure, n)) {
      out.image.convertTo(out.image, -1, e->value, 0.0);
    }
    if (find(FaultKind::kBlack, n)) out.image.setTo(cv::Scalar::all(0));
    if (find(FaultKind::kSaturated, n)) out.image.setTo(cv::Scalar::all(255));
    const bool corrupt = find(FaultKind::kCorrupt, n) != nullptr;
    if (corrupt || find(FaultKind::kTruncate, n)) {
      if (!reencode(out.image, n, corrupt)) {
        ++faults_;
        return SourceStatus::kFault;
      }
    }
    if (find(FaultKind::kZero, n)) out.image = cv::Mat();
    ++delivered_;
    return SourceStatus::kOk;
  }

  // JPEG round trip with damaged bytes through the strict MJPEG decoder (as a USB camera's
  // frame). False when the decoder rejects it; true with `image` decoded (garbled) otherwise.
  bool reencode(cv::Mat& image, int64_t n, bool corrupt) {
    if (image.empty()) return false;
    jpeg_.clear();
    if (!cv::imencode(".jpg", image, jpeg_, {cv::IMWRITE_JPEG_QUALITY, 90})) return false;
    size_t bytes = jpeg_.size();
    if (corrupt) {
      // Overwrite 48 bytes a third of the way into the entropy-coded data (after SOS).
      size_t sos = 0;
      for (size_t i = 0; i + 3 < bytes; ++i) {
        if (jpeg_[i] == 0xFF && jpeg_[i + 1] == 0xDA) {
          sos = i + 2 + ((size_t{jpeg_[i + 2]} << 8) | jpeg_[i + 3]);
          break;
        }
      }
      if (sos == 0 || sos >= bytes) return false;
      uint32_t lcg = static_cast<uint32_t>(n) * 2654435761u + 12345u;
      const size_t at = sos + (bytes - sos) / 3;
      for (size_t i = at; i < at + 48 && i + 2 < bytes; ++i) {
        lcg = lcg * 1664525u + 1013904223u;
        jpeg_[i] = static_cast<uint8_t>(lcg >> 24);
      }
    } else {
      bytes = bytes * 6 / 10;
    }
    return decoder_.decode(jpeg_.data(), bytes, image) == DecodeStatus::kOk;
  }

  std::unique_ptr<FrameSource> inner_;
  const std::vector<FaultSpan> plan_;
  SourceInfo info_;
  MjpegDecoder decoder_{true};
  std::vector<uint8_t> jpeg_;
  int64_t next_frame_ = 0;
  bool unplugged_ = false;
  bool have_stamp_ = false;
  int64_t last_stamp_ns_ = 0, last_interval_ns_ = 0;
  uint64_t skipped_ = 0, reopens_ = 0, faults_ = 0, delivered_ = 0;
};

}  // namespace

const char* to_string(FaultKind k) {
  for (const KindName& kn : kKinds) {
    if (kn.kind == k) return kn.name;
  }
  return "unknown";
}

std::vector<FaultSpan> parse_fault_spec(const std::string& spec) {
  std::vector<FaultSpan> plan;
  size_t pos = 0;
  while (pos <= spec.size()) {
    const size_t comma = std::min(spec.find(',', pos), spec.size());
    const std::string item = spec.substr(pos, comma - pos);
    pos = comma + 1;
    const size_t at = item.find('@');
    if (at == std::string::npos) bad_item(item, "no '@'");
    FaultSpan f;
    const std::string name = item.substr(0, at);
    bool known = false;
    for (const KindName& kn : kKinds) {
      if (name == kn.name) {
        f.kind = kn.kind;
        known = true;
      }
    }
    if (!known) bad_item(item, "unknown kind '" + name + "'");
    std::string range = item.substr(at + 1);
    const size_t colon = range.find(':');
    const bool has_value = colon != std::string::npos;
    if (has_value) {
      const std::string v = range.substr(colon + 1);
      range = range.substr(0, colon);
      if (f.kind != FaultKind::kExposure) bad_item(item, "only exposure takes a :VALUE");
      char* end = nullptr;
      errno = 0;
      f.value = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0' || errno != 0 || !(f.value >= 0.05 && f.value <= 20.0)) {
        bad_item(item, "exposure gain '" + v + "' is not a number in 0.05..20");
      }
    } else if (f.kind == FaultKind::kExposure) {
      bad_item(item, "exposure needs a gain, e.g. exposure@120-160:3");
    }
    const size_t dash = range.find('-');
    f.first = parse_frame(item, range.substr(0, dash));
    f.last = dash == std::string::npos ? f.first : parse_frame(item, range.substr(dash + 1));
    if (f.last < f.first) bad_item(item, "LAST is before FIRST");
    plan.push_back(f);
  }
  return plan;
}

std::unique_ptr<FrameSource> make_fault_injection_source(std::unique_ptr<FrameSource> inner,
                                                         std::vector<FaultSpan> plan) {
  if (!inner) throw std::runtime_error("--inject: no source");
  if (plan.empty()) return inner;
  return std::make_unique<FaultInjectionSource>(std::move(inner), std::move(plan));
}

}  // namespace rdslam
