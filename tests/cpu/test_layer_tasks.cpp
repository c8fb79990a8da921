// The tasks of the passes over listed bricks: every piece in exactly one task, each task within
// one layer of bricks, and layers cut only when there are too few of them for the threads.
#include <gtest/gtest.h>

#include <vector>

#include "cpu/layer_tasks.hpp"

using hpcm::cpu::tasks_by_layer;

namespace {

// Checks the invariants and returns the number of tasks.
std::size_t check_tasks(const std::vector<int>& layer, std::size_t min_tasks) {
  std::vector<std::size_t> starts{99, 98};  // stale content is replaced
  tasks_by_layer(layer.size(), [&](std::size_t i) { return layer[i]; }, min_tasks, starts);
  EXPECT_FALSE(starts.empty());
  EXPECT_EQ(starts.front(), 0u);
  EXPECT_EQ(starts.back(), layer.size());
  for (std::size_t t = 0; t + 1 < starts.size(); ++t) {
    EXPECT_LT(starts[t], starts[t + 1]) << "task " << t << " is empty";
    for (std::size_t i = starts[t]; i < starts[t + 1]; ++i)
      EXPECT_EQ(layer[i], layer[starts[t]]) << "task " << t << " crosses a layer at piece " << i;
  }
  return starts.size() - 1;
}

}  // namespace

TEST(LayerTasks, OneTaskPerLayerWhenThereAreEnough) {
  // 10 layers of 3, 1, 4, ... pieces
  std::vector<int> layer;
  for (int l = 0; l < 10; ++l)
    for (int k = 0; k < 1 + (l * 7) % 5; ++k) layer.push_back(l);
  EXPECT_EQ(check_tasks(layer, 8), 10u);
  EXPECT_EQ(check_tasks(layer, 1), 10u);
}

TEST(LayerTasks, FewLayersAreCutForTheThreads) {
  std::vector<int> layer(40, 3);            // one layer of 40 runs
  layer.insert(layer.end(), 2, 5);           // and one of 2
  // 2 layers, 8 tasks wanted: each layer in up to 4 parts; the small one only in 2.
  EXPECT_EQ(check_tasks(layer, 8), 4u + 2u);
  EXPECT_EQ(check_tasks(std::vector<int>(3, 0), 8), 3u);  // never more tasks than pieces
}

TEST(LayerTasks, NothingListed) {
  std::vector<std::size_t> starts{7};
  tasks_by_layer(0, [](std::size_t) { return 0; }, 8, starts);
  ASSERT_EQ(starts.size(), 1u);  // no task: a single boundary at 0
  EXPECT_EQ(starts[0], 0u);
}
