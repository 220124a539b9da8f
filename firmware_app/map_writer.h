// The map writer thread of `rdslam run` (issue 24: a save must not stall the tracker). The
// mapper thread serves a save request by copying the map (core/map_io.h copy_map_for_save:
// memory copies only) and hands the copy here; this thread does the expensive part (PNG
// encoding of the keyframe images, CRC-32, the fsync'ed atomic write: run_map_save_job,
// core/mapper.h) at nice `nice` (default 19: it runs on CPU time the pipeline threads leave
// over), pinned to the mapper's cores (threads.mapper_cores; any core when that is empty), so
// it never takes the tracker's CPU from it. One save at a time: requests made while one is
// being written are coalesced by the mapper into the next copy (SlamLink::saves_coalesced).
//
// Ownership: owns its thread and the job in progress. Threads: constructed, stop()ped and
// destroyed on the supervising thread; busy()/submit() from the mapper thread
// (MapSaveWriter); the job runs on the writer's own thread.
#pragma once

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "core/mapper.h"

namespace rdslam {

class MapWriter : public MapSaveWriter {
 public:
  // Starts the thread. `cores`: CPU cores it may run on (empty: any); `nice`: 0..19.
  MapWriter(const std::vector<int>& cores, int nice);
  ~MapWriter() override;  // stop()
  MapWriter(const MapWriter&) = delete;
  MapWriter& operator=(const MapWriter&) = delete;

  bool busy() const override { return busy_.load(std::memory_order_acquire); }
  // Mapper thread, only while !busy(): the thread writes `job` next.
  void submit(std::unique_ptr<MapSaveJob> job) override;
  // Finishes the job in progress (if any) and joins the thread; the mapper thread must have
  // stopped (no submit() after). Idempotent.
  void stop();

  uint64_t jobs_run() const { return jobs_run_.load(std::memory_order_relaxed); }

 private:
  void run(std::vector<int> cores, int nice);

  std::mutex mutex_;
  std::condition_variable cv_;
  std::unique_ptr<MapSaveJob> job_;  // guarded by mutex_
  bool stopping_ = false;            // guarded by mutex_
  std::atomic<bool> busy_{false};
  std::atomic<uint64_t> jobs_run_{0};
  std::thread thread_;
};

}  // namespace rdslam
