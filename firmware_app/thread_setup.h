// Scheduling of the calling thread (Linux): core pinning and nice. Shared by the pipeline's
// threads (pipeline.cpp), the map writer (map_writer.cpp) and the viewer publisher; each
// returns 0 or the error code and leaves the message to the caller, which knows the setting
// it applies. Header-only: the TSan stage of .ci/run compiles pipeline.cpp on its own.
//
// Threads: any thread, for itself only; call at its start (not on a real-time path).
#pragma once

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <vector>

namespace rdslam {

// Pins the calling thread to those of `cores` this machine has; the others are appended to
// *missing when given. 0, or pthread_setaffinity_np's error (EINVAL when none of them exists).
inline int pin_this_thread(const std::vector<int>& cores, std::vector<int>* missing = nullptr) {
  cpu_set_t set;
  CPU_ZERO(&set);
  const long ncpu = sysconf(_SC_NPROCESSORS_CONF);
  for (int c : cores) {
    if (c >= 0 && c < CPU_SETSIZE && c < ncpu) {
      CPU_SET(c, &set);
    } else if (missing != nullptr) {
      missing->push_back(c);
    }
  }
  return CPU_COUNT(&set) > 0 ? pthread_setaffinity_np(pthread_self(), sizeof(set), &set) : EINVAL;
}

// Linux: nice is per thread (setpriority on the thread id). 0, or errno. Raising it is always
// permitted; lowering it below 0 needs CAP_SYS_NICE.
inline int set_this_thread_nice(int nice) {
  errno = 0;
  return setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), nice) == 0 ? 0 : errno;
}

}  // namespace rdslam
