// Ordered-progress task runner (see parallel_tasks.hpp).
#include "host/residual/parallel_tasks.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace btsm::residual {

unsigned task_threads(unsigned requested, std::size_t tasks) {
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  const unsigned want = requested == 0 ? hw : requested;
  return static_cast<unsigned>(std::max<std::size_t>(1, std::min<std::size_t>(want, tasks)));
}

void run_tasks(std::size_t tasks, unsigned threads, const ProgressFn& progress,
               const std::function<void(std::size_t, const ProgressFn&)>& task) {
  if (tasks == 0) return;
  std::mutex m;
  std::size_t head = 0;  // the lowest unfinished task: its lines go out live
  std::vector<std::vector<std::string>> held(tasks);
  std::vector<bool> done(tasks, false);
  std::vector<std::exception_ptr> failed(tasks);
  const auto say_for = [&](std::size_t i) -> ProgressFn {
    if (!progress) return {};
    return [&, i](const std::string& s) {
      std::lock_guard<std::mutex> lock(m);
      if (i == head) progress(s);
      else held[i].push_back(s);
    };
  };
  const auto finish = [&](std::size_t i) {
    std::lock_guard<std::mutex> lock(m);
    done[i] = true;
    while (head < tasks && done[head]) {
      ++head;
      if (head < tasks && progress) {
        for (const auto& s : held[head]) progress(s);
        held[head].clear();
      }
    }
  };
  std::atomic<std::size_t> next{0};
  const auto worker = [&] {
    for (std::size_t i = next++; i < tasks; i = next++) {
      try {
        task(i, say_for(i));
      } catch (...) {
        failed[i] = std::current_exception();
      }
      finish(i);
    }
  };
  const unsigned n = task_threads(threads, tasks);
  std::vector<std::thread> others;
  for (unsigned t = 1; t < n; ++t) others.emplace_back(worker);
  worker();
  for (auto& t : others) t.join();
  for (const auto& e : failed)
    if (e) std::rethrow_exception(e);
}

}  // namespace btsm::residual
