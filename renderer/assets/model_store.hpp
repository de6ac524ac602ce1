// The models a server holds: uploaded ones by id ("sha256:<hex of the
// body>"), and those of --models DIR by id and by name (the file name
// without its extension). Bounded in bytes (TriangleModel::bytes()) and in
// count. Models from the folder are pinned (the operator chose them, and a
// scene naming "teapot" must not break because others uploaded), and count
// against the same budget.
//
// Every model this server loads for a client (an upload, or a file read
// from --model-store for a render) is charged to an owner (a token; "" for
// all clients of a server without tokens) and counted against the budget
// BEFORE it is built: the loader knows a bound on its bytes from its
// accessors, and reserve() makes room for that bound first. Room is made
// by dropping uploads least recently used first, but only those the owner
// may drop: its own; another owner's while that owner holds more than its
// share (room it borrowed); any model not used for `idle_drop`. So one
// owner's uploads never evict another owner's models within its share. A
// model a render still draws is never dropped to make room (dropping it
// would free nothing), and a dropped model a render still draws stays
// counted (live_bytes) until the render lets it go: the budget bounds the
// memory models really take, not only what the store lists.
//
// Pure and thread-safe: no GL, no HTTP. Tested in tests/test_model_store.cpp.
#pragma once

#include <atomic>
#include <chrono>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "core/model.hpp"

namespace umbra {

/// What the store holds of one model. Shared: a render that found it keeps
/// it alive (and counted, see drawn_model) even if the store drops it.
struct HeldModel {
  std::string id;
  std::string name;  ///< empty for an upload
  bool pinned = false;
  /// Whom it is charged to: who made this server load it ("" for pinned
  /// models and for a server without tokens).
  std::string owner;
  std::shared_ptr<const TriangleModel> model;
  std::uint64_t bytes = 0;  ///< model->bytes(), as counted against the budget
};

/// `held`'s model, keeping `held` alive while it is: what a render draws,
/// so that a model the store drops stays counted until the render ends.
std::shared_ptr<const TriangleModel> drawn_model(const std::shared_ptr<const HeldModel>& held);

class ModelStore {
 public:
  static constexpr std::size_t kDefaultMaxModels = 4096;
  /// A model not used (found, uploaded again, drawn) for this long may be
  /// dropped for anyone's new model.
  static constexpr std::chrono::seconds kDefaultIdleDrop{3600};

  struct Limits {
    std::uint64_t max_bytes = 0;
    std::size_t max_models = kDefaultMaxModels;
    /// What one owner's uploads may hold without being dropped for other
    /// owners' (--upload-quota-mib); 0: max_bytes. A single model larger
    /// than this is refused (Room::OverShare).
    std::uint64_t share_bytes = 0;
    std::chrono::seconds idle_drop = kDefaultIdleDrop;
  };
  using Clock = std::chrono::steady_clock;

  /// One owner ("") with the whole budget as its share.
  explicit ModelStore(std::uint64_t max_bytes, std::size_t max_models = kDefaultMaxModels);
  explicit ModelStore(const Limits& limits);
  ~ModelStore();
  ModelStore(const ModelStore&) = delete;
  ModelStore& operator=(const ModelStore&) = delete;

  /// Bytes counted for a model about to be loaded (or models: a scene's),
  /// until add_upload takes them or it is destroyed. Move-only. The store
  /// must outlive it.
  class Reservation {
   public:
    Reservation() = default;
    Reservation(Reservation&& other) noexcept;
    Reservation& operator=(Reservation&& other) noexcept;
    ~Reservation();
    std::uint64_t bytes() const { return bytes_; }
    const std::string& owner() const { return owner_; }

   private:
    friend class ModelStore;
    void release();
    ModelStore* store_ = nullptr;
    std::string owner_;
    std::uint64_t bytes_ = 0;
  };

  enum class Room {
    Made,        ///< reserved
    OverShare,   ///< more than an owner's share: never fits (422)
    OverBudget,  ///< more than the budget leaves beside the pinned models: never fits (422)
    NoRoomNow,   ///< the rest is held by other owners' models within their share, by models
                 ///< being drawn or by other loads' reservations (507 / 503, retry later)
  };
  struct RoomResult {
    Room outcome = Room::Made;
    Reservation reservation;  ///< holds `bytes` when Made
  };
  /// Makes room for `bytes` of models loaded for `owner`, dropping what it
  /// may (see above), and reserves it.
  RoomResult reserve(const std::string& owner, std::uint64_t bytes);
  /// Grows `reservation` to at least `bytes` (a load found its model larger
  /// than estimated), by the same rules. Made: it holds `bytes` now.
  Room grow(Reservation& reservation, std::uint64_t bytes);

  enum class Outcome {
    Added,
    AlreadyHeld,  ///< that id is held: `held` is the one already there
    TooLarge,     ///< more than the budget left once every unpinned model is dropped
    NameTaken,    ///< another model already has that name
    NoRoom,       ///< an upload found no room it may make (see Room::NoRoomNow)
  };
  struct AddResult {
    Outcome outcome;
    std::shared_ptr<const HeldModel> held;  ///< set for Added and AlreadyHeld
  };
  /// Holds `model` as an upload of `room`'s owner, in `room` (its bytes
  /// taken from it; if it holds fewer than model->bytes(), grown first).
  AddResult add_upload(const std::string& id, std::shared_ptr<const TriangleModel> model, Reservation& room);
  /// A pinned model (`name` may be empty); or, `pinned` false, an upload
  /// of owner "" that makes its own room (as add_upload after reserve).
  AddResult add(const std::string& id, const std::string& name, std::shared_ptr<const TriangleModel> model,
                bool pinned);

  /// Stops holding the upload `id` (one that could not be written to the
  /// shared folder, so is refused); false if it is not held.
  bool remove_upload(const std::string& id);

  /// By id or by name; made the most recently used. Null if not held.
  std::shared_ptr<const HeldModel> find(const std::string& id_or_name);
  /// Pinned models first (by name), then uploads, most recently used first.
  std::vector<std::shared_ptr<const HeldModel>> list() const;

  std::size_t count() const;
  /// Bytes of the models held (listed).
  std::uint64_t bytes() const;
  /// What the budget bounds: bytes of every model alive (held, or dropped
  /// but still drawn by a render) plus the reservations of loads under way.
  std::uint64_t live_bytes() const;
  /// Bytes of uploads held for `owner`.
  std::uint64_t owner_bytes(const std::string& owner) const;
  std::uint64_t max_bytes() const { return limits_.max_bytes; }
  std::uint64_t share_bytes() const { return limits_.share_bytes; }
  /// The budget less the pinned models: the most all uploads may hold.
  std::uint64_t upload_max_bytes() const;

  /// For tests: the clock that idle_drop is measured with.
  void set_clock(std::function<Clock::time_point()> now);

 private:
  struct Upload {
    std::shared_ptr<const HeldModel> held;
    Clock::time_point used;
  };
  struct Usage {
    std::uint64_t bytes = 0;
    std::size_t count = 0;
  };
  std::shared_ptr<const HeldModel> make_held(const std::string& id, const std::string& name, bool pinned,
                                             const std::string& owner, std::shared_ptr<const TriangleModel> model);
  // All under mutex_.
  std::uint64_t live_locked() const;
  Room limit_for(std::uint64_t bytes) const;
  bool may_drop(const Upload& upload, const std::string& owner, Clock::time_point now) const;
  // Drops uploads `owner` may drop, least recently used first, until
  // `fits` says so; false if it never does.
  bool drop_until(const std::string& owner, const std::function<bool()>& fits);
  void drop(std::list<Upload>::iterator it);
  Room make_room(const std::string& owner, std::uint64_t bytes);
  void touch(std::list<Upload>::iterator it);

  Limits limits_;
  std::size_t share_models_;
  std::function<Clock::time_point()> now_;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<const HeldModel>> pinned_;
  std::uint64_t pinned_bytes_ = 0;
  std::uint64_t upload_max_bytes_locked() const {
    return limits_.max_bytes - std::min(limits_.max_bytes, pinned_bytes_);
  }
  std::list<Upload> uploads_;  // most recently used first
  std::unordered_map<std::string, std::list<Upload>::iterator> by_id_;
  std::uint64_t upload_bytes_ = 0;
  std::map<std::string, Usage> owners_;
  std::uint64_t reserved_ = 0;
  // Bytes of every HeldModel alive, whoever holds it: each one's deleter
  // takes its bytes off, also after the store is gone (shared).
  std::shared_ptr<std::atomic<std::uint64_t>> alive_ = std::make_shared<std::atomic<std::uint64_t>>(0);
};

/// How much larger than its body an upload may be once loaded: at most
/// kUploadExpansion x its body + kUploadAllowance bytes. A mesh drawn once
/// loads to at most 12 times its body (uint8 triangle strips; a welded
/// mesh with normals about 1 time, 3 times for uint16 strips without
/// normals); only instancing (one mesh under many nodes, each copy built
/// out) goes further, and past the allowance an upload pays for its
/// copies with 1 body byte per 16 loaded.
constexpr std::uint64_t kUploadExpansion = 16;
constexpr std::uint64_t kUploadAllowance = std::uint64_t(32) << 20;
std::uint64_t max_loaded_bytes(std::uint64_t body_bytes);

/// Holds the built-in models (builtin_models.hpp), pinned under their
/// names, after a --models folder has been loaded: a folder's model of the
/// same name keeps that name (the built-in one stays reachable by its id),
/// and is reported in `not_held`, one line each, as is a built-in model
/// over the budget.
void hold_builtin_models(ModelStore& store, std::vector<std::string>& not_held);

/// The result of loading a --models folder.
struct FolderLoad {
  std::vector<std::shared_ptr<const HeldModel>> loaded;
  std::vector<std::string> refused;  ///< one line per file not loaded: "name.glb: why"
};

/// Loads every .glb and .gltf (any case) directly inside `folder`, pinned,
/// named by file name without extension, in file-name order. External
/// buffer files are read from inside the folder only; a model file whose
/// real path leaves the folder (a symlink) is refused. Files larger than
/// `max_file_bytes`, invalid models, names that are not [A-Za-z0-9._-]+
/// and models over the store's budget are refused, each with its reason.
/// The id of a folder model is the SHA-256 of its main file.
/// Returns false (with `error`) only if the folder cannot be read at all.
bool load_model_folder(const std::string& folder, ModelStore& store, std::size_t max_file_bytes, FolderLoad& result,
                       std::string& error);

}  // namespace umbra
