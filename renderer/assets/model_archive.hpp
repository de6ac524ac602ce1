// The folder that several servers share for uploaded models
// (--model-store DIR): each upload's body is written there once, named by
// its id, and a server that does not hold an id loads it from there before
// it calls the model unknown. So any request may land on any server of a
// cluster.
//
// Bounded on disk (--model-store-max-gib, counted in allocated blocks, and
// kDefaultMaxFiles models): before a file is written, the least recently
// used files its uploader may delete go until it fits. As in ModelStore,
// an upload deletes only its own owner's files, another owner's while that
// owner holds more than its share of the folder, and any file unused for
// idle_delete; otherwise NoRoomNow (507: room may come later). The owner
// (a principal, never a token; "" without tokens and for files of older
// servers) is kept in the record beside each model. "Used" is the file's mtime,
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
#include <unordered_map>

#include <sys/types.h>

#include "assets/gltf_loader.hpp"

namespace umbra {

class ModelArchive {
 public:
  static constexpr std::uint64_t kDefaultMaxBytes = std::uint64_t(8) << 30;
  /// The most model files the folder holds (so inodes are bounded too).
  static constexpr std::uint64_t kDefaultMaxFiles = 100000;
  /// A model file unused this long may be deleted for anyone's upload.
  static constexpr std::chrono::seconds kDefaultIdleDelete{24 * 3600};
  /// A temporary file of a write older than this was left by a crash: deleted.
  static constexpr std::chrono::seconds kStrayAfter{3600};
  /// A model's mtime is set at most this often while it is used.
  static constexpr std::chrono::seconds kTouchEvery{60};

  struct Limits {
    std::uint64_t max_bytes = kDefaultMaxBytes;  ///< allocated bytes (st_blocks * 512) of every file
    std::uint64_t max_files = kDefaultMaxFiles;  ///< model files
    /// What one owner's files may take without being deleted for other
    /// owners' uploads; 0: all of it (max_bytes, max_files).
    std::uint64_t share_bytes = 0;
    std::uint64_t share_files = 0;
    std::chrono::seconds idle_delete = kDefaultIdleDelete;
  };

  /// `folder` must exist (checked by the server at start).
  explicit ModelArchive(std::string folder, std::uint64_t max_bytes = kDefaultMaxBytes);
  ModelArchive(std::string folder, const Limits& limits);

  /// What a stored model holds once loaded (the "<hex>.json" beside it).
  struct Record {
    std::uint64_t bytes_bound = 0;  ///< LoadResult::bytes_bound
    std::uint64_t triangles = 0;
    std::string owner;  ///< who uploaded it first (a principal; "" for none)
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
    /// None: written by an older server, its record lost, or a record that
    /// claims more than an upload of this file may hold (max_loaded_bytes).
    std::optional<Record> record;
    std::string owner;  ///< the record's owner, also when its claim is not taken
  };

  enum class Status {
    Saved,
    TooLarge,   ///< larger than the folder's bound: never fits (422)
    NoRoomNow,  ///< the rest is other owners' files within their share (507, retry later)
    NoSpace,    ///< the disk is full even after evicting (507)
    Failed,     ///< any other error (503)
  };
  struct Saved {
    Status status = Status::Failed;
    /// For the server's log only: the path and the error (no client sees a path).
    std::string detail;
    explicit operator bool() const { return status == Status::Saved; }
  };

  /// Writes `body` as the file of `id` ("sha256:<64 hex>") unless that file
  /// is there already (then its mtime is set: used now), with `record`
  /// beside it. Makes room first (least recently used files go). Atomic:
  /// written to a temporary name in the folder, flushed to disk, then
  /// renamed, so no server ever reads half a file. Makes room for
  /// `record`'s owner ("" without a record); `why` (for a client: the id
  /// and the error, never a path) says why not.
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
  std::uint64_t max_bytes() const { return limits_.max_bytes; }
  const Limits& limits() const { return limits_; }
  /// Bytes in the folder when this server last counted them (at a save).
  std::uint64_t bytes_on_disk() const { return bytes_on_disk_.load(); }
  /// Model files this server deleted to make room.
  std::uint64_t evicted() const { return evicted_.load(); }

  /// For tests: how bytes reach the disk (default ::write), to feign ENOSPC.
  std::function<ssize_t(int fd, const void* data, std::size_t size)> write_for_test;

 private:
  struct Scan;
  // Reads the folder once: every model file, record and temporary file
  // (stray ones and orphan records deleted), owners from the records.
  Scan scan();
  // Deletes the least recently used model files (and their records) that
  // `owner` may delete until the folder holds at most `max_total` bytes and
  // `max_models` models, if it can get there; deletes nothing if it cannot
  // (false). Updates bytes_on_disk().
  bool evict_to(const std::string& owner, std::uint64_t max_total, std::uint64_t max_models);
  // One atomic write of `data` to `path`; errno-style result in `error`.
  bool write_file(const std::string& path, std::string_view data, int& error);
  std::string model_path(const std::string& id, LoadOptions::Format format) const;
  /// The size record beside the model whose id is "sha256:" + `hex`.
  std::string record_path(const std::string& hex) const;

  std::string folder_;
  Limits limits_;
  // Owners read from records, so a scan reads each record once: by hex,
  // with the record file's inode and mtime (a record replaced is read again).
  struct KnownOwner {
    std::uint64_t inode = 0;
    std::int64_t mtime_ns = 0;
    std::string owner;
  };
  std::mutex scan_mutex_;
  std::unordered_map<std::string, KnownOwner> owners_;
  std::atomic<std::uint64_t> bytes_on_disk_{0};
  std::atomic<std::uint64_t> evicted_{0};
  std::mutex touched_mutex_;
  std::map<std::string, std::chrono::steady_clock::time_point> touched_;
};

/// True for "sha256:" followed by 64 lowercase hex digits.
bool is_model_id(std::string_view id);

}  // namespace umbra
