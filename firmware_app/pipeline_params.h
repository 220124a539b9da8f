// Configuration of the pipeline runtime: the `pipeline` section (frame pool and rings,
// replay pacing) and the `threads` section (one row per pipeline thread: cores and
// priority), the PX4-style "one table" of who runs where.
//
// Ownership: plain values inside AppConfig. Threads: start-up only.
#pragma once

#include <string>
#include <vector>

#include "core/params.h"

namespace rdslam {

struct PipelineParams {
  int pool_slots = 8;               // preallocated frames shared by capture and tracker
  int output_ring_capacity = 64;    // tracker -> publisher messages (rounded up to 2^k)
  int read_timeout_ms = 100;        // capture: longest FrameSource::read() wait (stop latency)
  int mapper_step_timeout_ms = 50;  // mapper: longest MapperStage::step() wait
  int stats_period_ms = 1000;       // rdslam.status_t and the stats log line
  // Recorded sources in `rdslam run`: 1 = real time at the recorded timestamps (hardware in
  // the loop), X = X times real time, 0 = as fast as the tracker goes, lossless.
  double replay_speed = 1.0;
  // What `rdslam run` tracks with: "slam" (the SLAM system, core/slam.h) or "passthrough"
  // (publishes the source's ground truth, identity without it: for testing LCM consumers and
  // the runtime without the algorithm).
  std::string stages = "slam";

  void visit(ParamVisitor& v);
};

// One pipeline thread: the CPU cores it may run on (empty = any), its SCHED_FIFO priority
// (0 = normal SCHED_OTHER scheduling; 1..99 needs CAP_SYS_NICE or LimitRTPRIO) and, under
// SCHED_OTHER, its nice value (> 0 always permitted: yields CPU to the other threads;
// < 0 needs CAP_SYS_NICE or LimitNICE).
struct ThreadSpec {
  std::vector<int> cores;
  int priority = 0;
  int nice = 0;
};

struct ThreadParams {
  ThreadSpec capture;
  ThreadSpec tracker;
  ThreadSpec mapper;
  ThreadSpec publisher;
  // OpenCV's own thread pool (cv::setNumThreads, process-wide, applied by Pipeline::start):
  // -1 = as many threads as the pipeline threads have cores (the union of their core sets;
  // the process's CPU mask when one of them may run on any core), 0 = OpenCV runs every
  // function in the calling thread, N = N threads. Only the count: the pool's worker threads
  // are TBB's, which run on the process's mask (opencv_threads_for, firmware_app/pipeline.h).
  int opencv_threads = -1;

  void visit(ParamVisitor& v);
};

}  // namespace rdslam
