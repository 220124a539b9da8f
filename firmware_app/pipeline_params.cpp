#include "firmware_app/pipeline_params.h"

namespace rdslam {

void PipelineParams::visit(ParamVisitor& v) {
  v.field("pool_slots", pool_slots, 3, 256,
          "preallocated frames: one being written, one being tracked, the rest queued");
  v.field("output_ring_capacity", output_ring_capacity, 2, 65536,
          "tracker -> publisher pose messages; a full ring drops (counts) a message");
  v.field("read_timeout_ms", read_timeout_ms, 1, 2000,
          "longest wait in FrameSource::read(); bounds the shutdown time");
  v.field("mapper_step_timeout_ms", mapper_step_timeout_ms, 1, 1000,
          "longest wait in MapperStage::step(); bounds the shutdown time");
  v.field("stats_period_ms", stats_period_ms, 100, 60000,
          "period of rdslam.status_t and of the stats log line");
  v.field("replay_speed", replay_speed, 0.0, 1000.0,
          "recorded sources: 1 = real time, 0 = as fast as possible (lossless)");
  v.field("stages", stages, {"slam", "passthrough"},
          "run: slam, or passthrough (publishes ground truth; for testing consumers)");
}

namespace {
void visit_thread(ParamVisitor& v, ThreadSpec& t, const char* cores_key, const char* prio_key,
                  const char* nice_key) {
  v.field(cores_key, t.cores, 0, 1023, "CPU cores the thread may run on; empty = any");
  v.field(prio_key, t.priority, 0, 99, "SCHED_FIFO priority; 0 = normal scheduling");
  v.field(nice_key, t.nice, -20, 19,
          "nice value under normal scheduling; > 0 yields CPU to the other threads");
}
}  // namespace

void ThreadParams::visit(ParamVisitor& v) {
  visit_thread(v, capture, "capture_cores", "capture_priority", "capture_nice");
  visit_thread(v, tracker, "tracker_cores", "tracker_priority", "tracker_nice");
  visit_thread(v, mapper, "mapper_cores", "mapper_priority", "mapper_nice");
  visit_thread(v, publisher, "publisher_cores", "publisher_priority", "publisher_nice");
  v.field("opencv_threads", opencv_threads, -1, 1024,
          "OpenCV's thread pool: -1 = the cores of the pipeline threads, 0 = none (calling "
          "thread), N = N threads");
}

}  // namespace rdslam
