// The folder that several servers share for uploaded models
// (--model-store DIR): each upload's body is written there once, named by
// its id, and a server that does not hold an id loads it from there before
// it calls the model unknown. So any request may land on any server of a
// cluster. Pure: files, no HTTP, no GL. Tested in tests/test_model_store.cpp.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

#include "gltf_loader.hpp"

namespace umbra {

class ModelArchive {
 public:
  /// `folder` must exist (checked by the server at start).
  explicit ModelArchive(std::string folder);

  /// A model's body as stored, and how to read it.
  struct Stored {
    std::string body;
    LoadOptions::Format format = LoadOptions::Format::Binary;
  };

  /// Writes `body` as the file of `id` ("sha256:<64 hex>") unless that file
  /// is there already. Atomic: written to a temporary name in the folder,
  /// flushed to disk, then renamed, so no server ever reads half a file.
  /// False, with `why`, if it could not be written.
  bool save(const std::string& id, LoadOptions::Format format, std::string_view body, std::string& why) const;

  /// The stored body of `id`, if the folder has one of at most `max_bytes`
  /// whose SHA-256 is `id`: a file cut short or changed is not taken, and
  /// `why` says so. nullopt without a `why` when there is simply none, or
  /// when `id` is not of the form "sha256:<64 lowercase hex>" (a name: the
  /// folder is never asked for anything else, so no path can be formed from
  /// what a client sends).
  std::optional<Stored> load(const std::string& id, std::size_t max_bytes, std::string& why) const;

  const std::string& folder() const { return folder_; }

 private:
  std::string folder_;
};

/// True for "sha256:" followed by 64 lowercase hex digits.
bool is_model_id(std::string_view id);

}  // namespace umbra
