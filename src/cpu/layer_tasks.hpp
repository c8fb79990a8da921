#pragma once
// Tasks for the passes over listed bricks (velocity layer, link check).
#include <cstddef>
#include <vector>

namespace hpcm::cpu {

/// Task boundaries for `count` pieces of work (brick runs or spans) listed in brick order,
/// layer of bricks (bz) first: task t covers pieces [starts[t], starts[t + 1]), all in one
/// layer. A task walks its layer plane by plane over all of its pieces, so each array is read
/// in long sequential stretches that the hardware prefetcher follows; piece by piece it would
/// read a brick's 8 rows and jump to the next plane. Only where there are fewer layers than
/// `min_tasks` is a layer cut into consecutive parts, so that the threads still share the work.
/// `layer_of(i)`: the layer of piece i.
template <class LayerOf>
void tasks_by_layer(std::size_t count, LayerOf layer_of, std::size_t min_tasks, std::vector<std::size_t>& starts) {
  std::size_t layers = 0;
  for (std::size_t i = 0; i < count; ++i)
    if (i == 0 || layer_of(i) != layer_of(i - 1)) ++layers;
  const std::size_t parts = layers > 0 && layers < min_tasks ? (min_tasks + layers - 1) / layers : 1;
  starts.clear();
  for (std::size_t begin = 0; begin < count;) {
    std::size_t end = begin + 1;
    while (end < count && layer_of(end) == layer_of(begin)) ++end;
    for (std::size_t p = 0; p < parts; ++p) {  // consecutive parts, none empty
      const std::size_t s = begin + (end - begin) * p / parts;
      if (starts.empty() || s != starts.back()) starts.push_back(s);
    }
    begin = end;
  }
  starts.push_back(count);
}

/// Tasks per pass: enough for the threads to share a pass over a few layers of bricks.
inline std::size_t min_layer_tasks(int threads) { return threads > 1 ? 4 * static_cast<std::size_t>(threads) : 1; }

}  // namespace hpcm::cpu
