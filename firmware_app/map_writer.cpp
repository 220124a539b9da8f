#include "firmware_app/map_writer.h"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/log.h"
#include "firmware_app/thread_setup.h"

namespace rdslam {

MapWriter::MapWriter(const std::vector<int>& cores, int nice)
    : thread_(&MapWriter::run, this, cores, nice) {}

MapWriter::~MapWriter() {
  stop();
}

void MapWriter::submit(std::unique_ptr<MapSaveJob> job) {
  busy_.store(true, std::memory_order_release);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = std::move(job);
  }
  cv_.notify_one();
}

void MapWriter::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
}

void MapWriter::run(std::vector<int> cores, int nice) {
  pthread_setname_np(pthread_self(), "rdslam-mapsave");
  if (!cores.empty()) {
    const int rc = pin_this_thread(cores);
    if (rc != 0) {
      RDSLAM_LOG_WARN("map writer: cannot pin to the mapper's cores: %s; running unpinned",
                      std::strerror(rc));
    }
  }
  if (nice != 0) {
    const int rc = set_this_thread_nice(nice);
    if (rc != 0) RDSLAM_LOG_WARN("map writer: nice %d not permitted: %s", nice, std::strerror(rc));
  }
  for (;;) {
    std::unique_ptr<MapSaveJob> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] { return stopping_ || job_ != nullptr; });
      job = std::move(job_);
    }
    if (job) {
      run_map_save_job(*job);
      job.reset();  // the copy's memory goes before the mapper may make the next one
      jobs_run_.fetch_add(1, std::memory_order_relaxed);
      busy_.store(false, std::memory_order_release);
      continue;
    }
    return;  // stopping, nothing left to write
  }
}

}  // namespace rdslam
