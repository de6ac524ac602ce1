// The models a server holds: uploaded ones by id ("sha256:<hex of the
// body>"), and those of --models DIR by id and by name (the file name
// without its extension). Bounded in bytes (TriangleModel::bytes()) and in
// count: uploads are dropped least recently used first; models from the
// folder are pinned (the operator chose them, and a scene naming
// "teapot" must not break because others uploaded), and count against
// the same budget. Pure and thread-safe: no GL, no HTTP. Tested in
// tests/test_model_store.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "byte_bounded_lru.hpp"
#include "model.hpp"

namespace umbra {

/// What the store holds of one model. Shared: a render that found it keeps
/// it alive even if the store drops it meanwhile.
struct HeldModel {
  std::string id;
  std::string name;  ///< empty for an upload
  bool pinned = false;
  std::shared_ptr<const TriangleModel> model;
  std::uint64_t bytes = 0;  ///< model->bytes(), as counted against the budget
};

class ModelStore {
 public:
  static constexpr std::size_t kDefaultMaxModels = 4096;

  explicit ModelStore(std::uint64_t max_bytes, std::size_t max_models = kDefaultMaxModels);

  enum class Outcome {
    Added,
    AlreadyHeld,  ///< that id is held: `held` is the one already there
    TooLarge,     ///< more than the budget left once every unpinned model is dropped
    NameTaken,    ///< another model already has that name
  };
  struct AddResult {
    Outcome outcome;
    std::shared_ptr<const HeldModel> held;  ///< set for Added and AlreadyHeld
  };
  /// Holds `model` under `id` (and `name`, if not empty). An unpinned add
  /// drops least recently used uploads until everything fits.
  AddResult add(const std::string& id, const std::string& name, std::shared_ptr<const TriangleModel> model,
                bool pinned);

  /// By id or by name; made the most recently used. Null if not held.
  std::shared_ptr<const HeldModel> find(const std::string& id_or_name);
  /// Pinned models first (by name), then uploads, most recently used first.
  std::vector<std::shared_ptr<const HeldModel>> list() const;

  std::size_t count() const;
  std::uint64_t bytes() const;
  std::uint64_t max_bytes() const { return max_bytes_; }

 private:
  const std::uint64_t max_bytes_;
  const std::size_t max_models_;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<const HeldModel>> pinned_;
  std::uint64_t pinned_bytes_ = 0;
  ByteBoundedLru<std::shared_ptr<const HeldModel>> uploads_;  // keyed by id
};

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
