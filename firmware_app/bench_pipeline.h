// `rdslam bench pipeline SOURCE`: the throughput / latency benchmark of issue 10. One row of
// the `rdslam bench` dispatcher (firmware_app/cmd_bench.cpp).
//
// Default mode: the full threaded pipeline (firmware_app/pipeline.h, lossless replay as fast
// as the stages go) with the SLAM stages (core/slam.h). Reports per-stage times (p50, p99 ms
// from the pipeline's whole-run histograms), throughput fps, capture-to-publish latency and
// peak RSS; --json prints the common report keys (firmware_app/report.h) plus `stages`
// {`tracker`, `mapper`, `capture`, `publish`: {`p50`, `p99`}}.
//
// --single-thread: run_offline() in the calling thread (deterministic; for callgrind, whose
// instruction counts per frame are then comparable between commits).
//
// Threads: call from main only.
#pragma once

namespace rdslam {

int bench_pipeline(int argc, char** argv);

}  // namespace rdslam
