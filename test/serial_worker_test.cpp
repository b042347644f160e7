#include "multisession_mapper/core/serial_worker.h"

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// Tasks run one at a time, in the order posted, off the posting thread; Wait returns after
// the last one.
TEST(SerialWorkerTest, RunsTasksInOrderOffTheCallersThread) {
  std::vector<int> order;  // touched by the tasks only until Wait
  std::atomic<int> running{0};
  std::atomic<int> overlap{0};
  std::atomic<int> on_caller{0};
  const std::thread::id caller = std::this_thread::get_id();
  SerialWorker worker(4);
  for (int i = 0; i < 200; ++i) {
    worker.Post([&, i] {
      if (running.fetch_add(1) != 0) ++overlap;
      if (std::this_thread::get_id() == caller) ++on_caller;
      if (i % 50 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      order.push_back(i);
      running.fetch_sub(1);
    });
  }
  worker.Wait();
  ASSERT_EQ(order.size(), 200u);
  for (int i = 0; i < 200; ++i) EXPECT_EQ(order[i], i);
  EXPECT_EQ(overlap.load(), 0);
  EXPECT_EQ(on_caller.load(), 0);
}

// Post blocks while max_pending tasks wait or run: a blocked task holds the queue full.
TEST(SerialWorkerTest, PostBlocksWhileTheQueueIsFull) {
  std::atomic<bool> release{false};
  std::atomic<int> posted{0};
  SerialWorker worker(2);
  worker.Post([&] {
    while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  });
  worker.Post([] {});
  std::thread poster([&] {
    worker.Post([] {});  // the third: waits for the first to finish
    ++posted;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(posted.load(), 0);
  release = true;
  poster.join();
  EXPECT_EQ(posted.load(), 1);
  worker.Wait();
}

// The destructor runs what is still queued before it stops.
TEST(SerialWorkerTest, DestructorRunsTheRemainingTasks) {
  std::atomic<int> done{0};
  {
    SerialWorker worker(100);
    for (int i = 0; i < 50; ++i) {
      worker.Post([&] {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        ++done;
      });
    }
  }
  EXPECT_EQ(done.load(), 50);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
