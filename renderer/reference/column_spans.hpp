// Stretches of a grid row's columns, as the sun-hours footprints and the
// mesh shadows hand them to the walk: merged, and one less another.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace umbra {

/// Columns [first, last] of a grid row.
struct ColumnSpan {
  int first, last;
};

/// Sorts a row's spans and joins those that overlap or touch.
inline void merge_spans(std::vector<ColumnSpan>& spans) {
  if (spans.size() < 2) return;
  std::sort(spans.begin(), spans.end(), [](const ColumnSpan& a, const ColumnSpan& b) { return a.first < b.first; });
  std::size_t kept = 0;
  for (std::size_t i = 1; i < spans.size(); ++i) {
    if (spans[i].first <= spans[kept].last + 1)
      spans[kept].last = std::max(spans[kept].last, spans[i].last);
    else
      spans[++kept] = spans[i];
  }
  spans.resize(kept + 1);
}

/// Calls f(first, last) for each stretch of columns in `from` (merged
/// spans, `count` of them) that no span of `without` (merged spans,
/// `without_count` of them) holds, in order.
template <class F>
void for_each_difference(const ColumnSpan* from, std::size_t count, const ColumnSpan* without,
                         std::size_t without_count, F&& f) {
  std::size_t w = 0;
  for (const ColumnSpan* span = from; span != from + count; ++span) {
    int c = span->first;
    while (w < without_count && without[w].last < c) ++w;
    for (std::size_t v = w; c <= span->last; ++v) {
      if (v == without_count || without[v].first > span->last) {
        f(c, span->last);
        break;
      }
      if (without[v].first > c) f(c, without[v].first - 1);
      c = std::max(c, without[v].last + 1);
    }
  }
}
template <class F>
void for_each_difference(const ColumnSpan* from, std::size_t count, const std::vector<ColumnSpan>& without, F&& f) {
  for_each_difference(from, count, without.data(), without.size(), f);
}
template <class F>
void for_each_difference(const std::vector<ColumnSpan>& from, const std::vector<ColumnSpan>& without, F&& f) {
  for_each_difference(from.data(), from.size(), without.data(), without.size(), f);
}

}  // namespace umbra
