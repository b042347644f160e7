#include "multisession_mapper/core/bounded_queue.h"

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// Items pass from a producer thread to the consumer in the order pushed, and Pop(true) ends
// with nullopt once the producer closed the queue and everything was taken.
TEST(BoundedQueueTest, PassesItemsInOrderAndEndsAfterClose) {
  BoundedQueue<int> queue(3);
  std::thread producer([&] {
    for (int i = 0; i < 500; ++i) {
      if (i % 100 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      EXPECT_TRUE(queue.Push(i));
    }
    queue.Close();
  });
  std::vector<int> received;
  while (std::optional<int> item = queue.Pop(true)) received.push_back(*item);
  producer.join();
  ASSERT_EQ(received.size(), 500u);
  for (int i = 0; i < 500; ++i) EXPECT_EQ(received[i], i);
}

// Pop without wait returns at once: nullopt when nothing is queued, the oldest item otherwise.
TEST(BoundedQueueTest, PopWithoutWaitDoesNotBlock) {
  BoundedQueue<int> queue(4);
  EXPECT_FALSE(queue.Pop(false).has_value());
  ASSERT_TRUE(queue.Push(7));
  ASSERT_TRUE(queue.Push(8));
  EXPECT_EQ(queue.Pop(false).value_or(-1), 7);
  EXPECT_EQ(queue.Pop(false).value_or(-1), 8);
  EXPECT_FALSE(queue.Pop(false).has_value());
}

// Push waits while `capacity` items are queued and goes on once one is taken.
TEST(BoundedQueueTest, PushWaitsWhileFull) {
  BoundedQueue<int> queue(2);
  ASSERT_TRUE(queue.Push(1));
  ASSERT_TRUE(queue.Push(2));
  std::atomic<bool> pushed{false};
  std::thread producer([&] {
    EXPECT_TRUE(queue.Push(3));
    pushed = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(pushed.load());
  EXPECT_EQ(queue.Pop(false).value_or(-1), 1);
  producer.join();
  EXPECT_TRUE(pushed.load());
  EXPECT_EQ(queue.Pop(false).value_or(-1), 2);
  EXPECT_EQ(queue.Pop(false).value_or(-1), 3);
}

// Closing releases a producer that waits on a full queue (its item is refused) and a consumer
// that waits on an empty one; items queued before the close are still delivered.
TEST(BoundedQueueTest, CloseReleasesWaitingThreads) {
  BoundedQueue<int> full(1);
  ASSERT_TRUE(full.Push(1));
  std::atomic<int> push_result{-1};
  std::thread producer([&] { push_result = full.Push(2) ? 1 : 0; });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(push_result.load(), -1);
  full.Close();
  producer.join();
  EXPECT_EQ(push_result.load(), 0);
  EXPECT_EQ(full.Pop(true).value_or(-1), 1);
  EXPECT_FALSE(full.Pop(true).has_value());
  EXPECT_FALSE(full.Push(3));

  BoundedQueue<int> empty(1);
  std::atomic<bool> returned{false};
  std::thread consumer([&] {
    EXPECT_FALSE(empty.Pop(true).has_value());
    returned = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_FALSE(returned.load());
  empty.Close();
  consumer.join();
  EXPECT_TRUE(returned.load());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
