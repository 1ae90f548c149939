/*=========================================================================
 *
 *  Copyright NumFOCUS
 *
 *  Licensed under the Apache License, Version 2.0 (the "License");
 *  you may not use this file except in compliance with the License.
 *  You may obtain a copy of the License at
 *
 *         http://www.apache.org/licenses/LICENSE-2.0.txt
 *
 *  Unless required by applicable law or agreed to in writing, software
 *  distributed under the License is distributed on an "AS IS" BASIS,
 *  WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
 *  See the License for the specific language governing permissions and
 *  limitations under the License.
 *
 *=========================================================================*/
#ifndef dcvParallel_h
#define dcvParallel_h

// Internal to the compiled sources: the one way the encoder spreads work over threads (TBB).
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_sort.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstddef>
#include <optional>
#include <utility>
#include <vector>

namespace dcv
{

/** Calls f(i) for every i in [0, n) on the threads of the current task arena. Each f(i) must write only
 * its own results: callers then combine them in index order, so that what they compute does not
 * depend on the number of threads or on how the range was split. */
template <typename F>
void
ParallelFor(std::size_t n, std::size_t grain, F && f)
{
  if (n <= grain)
  {
    for (std::size_t i = 0; i < n; ++i)
    {
      f(i);
    }
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&f](const tbb::blocked_range<std::size_t> & r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i)
    {
      f(i);
    }
  });
}

/** Calls f() and g() side by side on the threads of the current task arena (one after the other where
 * no other thread is free); each must write only its own results. */
template <typename F, typename G>
void
ParallelInvoke(F && f, G && g)
{
  tbb::parallel_invoke(f, g);
}

/** Sorts [first, last) on the threads of the current task arena: for keys that are all distinct, so that
 * the order does not depend on the threads (std::sort's, where they are). */
template <typename Iterator>
void
ParallelSort(Iterator first, Iterator last)
{
  tbb::parallel_sort(first, last);
}

/** Blocks of a pass over a volume's voxels (ParallelMinMax, ParallelCount): a serial pass over 67 MB of
 * floats was some 15 ms on norm-256, and the encoder made several before its first point. */
constexpr std::size_t PassBlock = std::size_t(1) << 20;

/** The blocks of PassBlock values that n values make. */
constexpr std::size_t
PassBlocks(std::size_t n)
{
  return (n + PassBlock - 1) / PassBlock;
}

/** f(b, first, last) for each block b of PassBlock values of [data, data + n), on the threads. */
template <typename T, typename F>
void
ForEachPassBlock(const T * data, std::size_t n, F && f)
{
  ParallelFor(PassBlocks(n), 1, [&](std::size_t b) {
    const T * first = data + b * PassBlock;
    f(b, first, first + std::min(PassBlock, n - b * PassBlock));
  });
}

/** The values std::minmax_element gives over [data, data + n) (n > 0), on the threads: each block's, then
 * the blocks' in order (the first smallest, the last largest), so the same values, -0 and +0 included,
 * wherever no value is NaN. */
template <typename T>
std::pair<T, T>
ParallelMinMax(const T * data, std::size_t n)
{
  std::vector<std::pair<T, T>> ranges(PassBlocks(n));
  ForEachPassBlock(data, n, [&](std::size_t b, const T * first, const T * last) {
    const auto range = std::minmax_element(first, last);
    ranges[b] = { *range.first, *range.second };
  });
  std::pair<T, T> out = ranges.at(0);
  for (std::size_t b = 1; b < ranges.size(); ++b)
  {
    if (ranges[b].first < out.first)
      out.first = ranges[b].first;
    if (!(ranges[b].second < out.second))
      out.second = ranges[b].second;
  }
  return out;
}

/** The number of values of [data, data + n) that satisfy `predicate`, on the threads. */
template <typename T, typename P>
std::size_t
ParallelCount(const T * data, std::size_t n, P && predicate)
{
  std::vector<std::size_t> counts(PassBlocks(n));
  ForEachPassBlock(data, n, [&](std::size_t b, const T * first, const T * last) {
    counts[b] = std::size_t(std::count_if(first, last, predicate));
  });
  std::size_t total = 0;
  for (const std::size_t c : counts)
    total += c;
  return total;
}

/** The number of threads ParallelFor uses here (that of the current task arena). */
inline unsigned int
CurrentThreads()
{
  return unsigned(std::max(1, tbb::this_task_arena::max_concurrency()));
}

/** Runs f with at most `threads` threads for the ParallelFor calls it makes (0: one per core). */
template <typename F>
decltype(auto)
WithThreads(unsigned int threads, F && f)
{
  // More threads than cores: TBB keeps its workers to the cores unless told otherwise (and says so on
  // stderr, whatever --quiet asked).
  std::optional<tbb::global_control> allowed;
  if (threads > unsigned(std::max(1, tbb::info::default_concurrency())))
    allowed.emplace(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
  tbb::task_arena arena(threads == 0 ? tbb::task_arena::automatic : int(threads));
  return arena.execute(f);
}

} // namespace dcv

#endif
