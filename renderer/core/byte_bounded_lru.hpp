// A least-recently-used cache bounded in bytes (and entries): what the
// renderer keeps between requests must fit its share of the memory budget
// (ServiceLimits::memory_budget_bytes), whatever sizes clients ask for.
//
// Pure code, no GL: the values may own GL objects (the renderer's scenes do),
// but this only moves and destroys them, on the thread that calls it.
// Unit tested in tests/test_byte_bounded_lru.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <list>
#include <string>
#include <utility>

namespace umbra {

template <class Value>
class ByteBoundedLru {
 public:
  struct Entry {
    std::string key;
    Value value;
    std::uint64_t bytes = 0;  ///< what the value holds, as its owner counts it
  };

  /// The entry for `key`, made the most recently used; nullptr if absent.
  Entry* find(const std::string& key) {
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (it->key != key) continue;
      entries_.splice(entries_.begin(), entries_, it);
      return &entries_.front();
    }
    return nullptr;
  }

  /// Adds `value` as the most recently used entry (the caller has checked
  /// that `key` is absent). Evicts nothing: call evict_to after.
  Entry& insert(std::string key, Value value, std::uint64_t bytes) {
    entries_.push_front(Entry{std::move(key), std::move(value), bytes});
    bytes_ += bytes;
    return entries_.front();
  }

  /// Drops least recently used entries while more than `max_bytes` or more
  /// than `max_entries` are held, but never the `keep` most recent (the one
  /// being drawn). Returns the bytes dropped.
  std::uint64_t evict_to(std::uint64_t max_bytes, std::size_t max_entries, std::size_t keep = 0) {
    std::uint64_t dropped = 0;
    while (entries_.size() > keep && (bytes_ > max_bytes || entries_.size() > max_entries)) {
      dropped += entries_.back().bytes;
      bytes_ -= entries_.back().bytes;
      entries_.pop_back();
    }
    return dropped;
  }

  /// Calls f(entry) for each entry, most recently used first, touching none.
  template <class F>
  void for_each(F&& f) const {
    for (const Entry& e : entries_) f(e);
  }

  bool empty() const { return entries_.empty(); }
  std::size_t size() const { return entries_.size(); }
  std::uint64_t bytes() const { return bytes_; }
  /// The most recently used entry; the cache must not be empty.
  Entry& front() { return entries_.front(); }
  const Entry& front() const { return entries_.front(); }

 private:
  std::list<Entry> entries_;  // most recently used first
  std::uint64_t bytes_ = 0;
};

}  // namespace umbra
