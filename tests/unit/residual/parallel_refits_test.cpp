// The task runner that puts the residual loop's independent refits side by side without changing
// its answer: results and progress in task order whatever the thread count.
#include "host/residual/parallel_tasks.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace btsm::residual {
namespace {

// Task i sleeps longer the earlier it comes, so with several threads the later tasks finish first:
// their lines must still come out after every line of the earlier ones.
std::vector<std::string> run_and_collect(unsigned threads, std::vector<int>& results) {
  std::vector<std::string> lines;
  const std::size_t n = 5;
  results.assign(n, -1);
  run_tasks(n, threads, [&](const std::string& s) { lines.push_back(s); }, [&](std::size_t i, const ProgressFn& say) {
    say("task " + std::to_string(i) + " starts");
    std::this_thread::sleep_for(std::chrono::milliseconds(10 * static_cast<int>(n - i)));
    results[i] = static_cast<int>(i * i);
    say("task " + std::to_string(i) + " ends");
  });
  return lines;
}

TEST(ParallelTasks, ResultsAndProgressAreInTaskOrderWhateverTheThreadCount) {
  std::vector<std::string> expected;
  for (int i = 0; i < 5; ++i) {
    expected.push_back("task " + std::to_string(i) + " starts");
    expected.push_back("task " + std::to_string(i) + " ends");
  }
  for (unsigned threads : {1u, 2u, 4u}) {
    std::vector<int> results;
    EXPECT_EQ(run_and_collect(threads, results), expected) << threads << " threads";
    EXPECT_EQ(results, (std::vector<int>{0, 1, 4, 9, 16})) << threads << " threads";
  }
  EXPECT_EQ(task_threads(0, 1), 1u);   // never more threads than tasks
  EXPECT_EQ(task_threads(3, 10), 3u);
  EXPECT_GE(task_threads(0, 10), 1u);  // 0 = the machine's cores
}

TEST(ParallelTasks, AFailingTaskIsRethrownAfterTheOthersRan) {
  std::vector<int> ran(4, 0);
  EXPECT_THROW(run_tasks(4, 2, {}, [&](std::size_t i, const ProgressFn&) {
                 ran[i] = 1;
                 if (i == 1) throw std::runtime_error("task 1 failed");
               }),
               std::runtime_error);
  EXPECT_EQ(ran, (std::vector<int>{1, 1, 1, 1}));
}

}  // namespace
}  // namespace btsm::residual
