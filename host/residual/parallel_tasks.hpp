#pragma once
// Independent refits (candidates, rivals, node drops) run side by side on the machine's cores.
// Each task computes from its own inputs only, so the results do not depend on the thread count;
// the progress lines keep the order a sequential run prints them in (the lowest unfinished task
// speaks live, the later ones are held until every earlier one has finished).
#include <cstddef>
#include <functional>
#include <string>

namespace btsm::residual {

using ProgressFn = std::function<void(const std::string&)>;

// The threads `requested` asks for: 0 = the hardware's cores; never more than `tasks`, at least 1.
unsigned task_threads(unsigned requested, std::size_t tasks);

// Runs task(i, say) for i = 0 .. tasks-1 on task_threads(threads, tasks) threads; `say` forwards
// to `progress` (may be empty) in task order. The first exception a task throws (lowest index) is
// rethrown after all tasks have ended.
void run_tasks(std::size_t tasks, unsigned threads, const ProgressFn& progress,
               const std::function<void(std::size_t, const ProgressFn&)>& task);

}  // namespace btsm::residual
