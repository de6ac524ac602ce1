// The folder that several servers share for uploaded models
// (--model-store DIR): each upload's body is written there once, named by
// its id, and a server that does not hold an id loads it from there before
// it calls the model unknown. So any request may land on any server of a
// cluster.
//
// Bounded on disk (--model-store-max-gib): before a file is written, the
// least recently used files go until it fits. "Used" is the file's mtime,
// which every server sets when it writes, loads or draws a model (at most
// once a minute per model), so eviction is a function of what is on disk,
// and servers sharing the folder agree on it without talking. Two servers
// evicting at once may both delete (a missing file is simply gone) and
// together delete a little more than needed, never less. Writes are atomic
// (a temporary name, then rename). A model deleted by one server is unknown
// to the others (400 "unknown model" naming it) until it is uploaded again;
// a server that holds it in memory keeps drawing it and writes it back when
// it is uploaded again. A full disk (ENOSPC) first evicts, then tries once
// more, then answers NoSpace (507): never a refusal that lasts while the
// folder holds files it may delete.
//
// Beside each model, "<hex>.json" records what it holds once loaded (a
// bound on its bytes, its triangles), so that a server can count a stored
// model against its memory budget before it reads or builds it.
//
// Pure: files, no HTTP, no GL. Tested in tests/test_model_store.cpp.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

#include <sys/types.h>

#include "gltf_loader.hpp"

namespace umbra {

class ModelArchive {
 public:
  static constexpr std::uint64_t kDefaultMaxBytes = std::uint64_t(8) << 30;
  /// A temporary file of a write older than this was left by a crash: deleted.
  static constexpr std::chrono::seconds kStrayAfter{3600};
  /// A model's mtime is set at most this often while it is used.
  static constexpr std::chrono::seconds kTouchEvery{60};

  /// `folder` must exist (checked by the server at start).
  explicit ModelArchive(std::string folder, std::uint64_t max_bytes = kDefaultMaxBytes);

  /// What a stored model holds once loaded (the "<hex>.json" beside it).
  struct Record {
    std::uint64_t bytes_bound = 0;  ///< LoadResult::bytes_bound
    std::uint64_t triangles = 0;
  };

  /// A model's body as stored, and how to read it.
  struct Stored {
    std::string body;
    LoadOptions::Format format = LoadOptions::Format::Binary;
  };

  /// What the folder has of `id` without reading its body.
  struct Found {
    LoadOptions::Format format = LoadOptions::Format::Binary;
    std::uint64_t file_bytes = 0;
    std::optional<Record> record;  ///< none: written by an older server, or its record lost
  };

  enum class Status { Saved, NoSpace, Failed };
  struct Saved {
    Status status = Status::Failed;
    explicit operator bool() const { return status == Status::Saved; }
  };

  /// Writes `body` as the file of `id` ("sha256:<64 hex>") unless that file
  /// is there already (then its mtime is set: used now), with `record`
  /// beside it. Makes room first (least recently used files go). Atomic:
  /// written to a temporary name in the folder, flushed to disk, then
  /// renamed, so no server ever reads half a file. NoSpace: larger than
  /// the folder's bound, or the disk is full even after evicting; Failed:
  /// any other error. `why` says which.
  Saved save(const std::string& id, LoadOptions::Format format, std::string_view body, std::string& why,
             const std::optional<Record>& record = std::nullopt);

  /// Writes (or replaces) the record of `id`, if its model file is there.
  void write_record(const std::string& id, const Record& record);

  /// The stored body of `id`, if the folder has one of at most `max_bytes`
  /// whose SHA-256 is `id`: a file cut short or changed is not taken, and
  /// `why` says so. nullopt without a `why` when there is simply none, or
  /// when `id` is not of the form "sha256:<64 lowercase hex>" (a name: the
  /// folder is never asked for anything else, so no path can be formed from
  /// what a client sends). Counts as a use (touch).
  std::optional<Stored> load(const std::string& id, std::size_t max_bytes, std::string& why);

  /// Whether the folder has `id`, its size and its record; reads no body.
  std::optional<Found> find(const std::string& id) const;

  /// Sets the mtime of `id`'s file to now (at most once per kTouchEvery
  /// per id from this server): it was used, so it is evicted last.
  void touch(const std::string& id);

  const std::string& folder() const { return folder_; }
  std::uint64_t max_bytes() const { return max_bytes_; }
  /// Bytes in the folder when this server last counted them (at a save).
  std::uint64_t bytes_on_disk() const { return bytes_on_disk_.load(); }
  /// Model files this server deleted to make room.
  std::uint64_t evicted() const { return evicted_.load(); }

  /// For tests: how bytes reach the disk (default ::write), to feign ENOSPC.
  std::function<ssize_t(int fd, const void* data, std::size_t size)> write_for_test;

 private:
  // Deletes least recently used model files (and their records) until the
  // folder holds at most `max_total` bytes; also stray temporary files and
  // orphan records. Returns the bytes in the folder afterwards.
  std::uint64_t evict_to(std::uint64_t max_total);
  // One atomic write of `data` to `path`; errno-style result in `error`.
  bool write_file(const std::string& path, std::string_view data, int& error);
  std::string model_path(const std::string& id, LoadOptions::Format format) const;

  std::string folder_;
  std::uint64_t max_bytes_;
  std::atomic<std::uint64_t> bytes_on_disk_{0};
  std::atomic<std::uint64_t> evicted_{0};
  std::mutex touched_mutex_;
  std::map<std::string, std::chrono::steady_clock::time_point> touched_;
};

/// True for "sha256:" followed by 64 lowercase hex digits.
bool is_model_id(std::string_view id);

}  // namespace umbra
