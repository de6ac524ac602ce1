#include "model_store.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <utility>

#include "builtin_models.hpp"
#include "gltf_loader.hpp"

namespace umbra {

ModelStore::ModelStore(std::uint64_t max_bytes, std::size_t max_models) : max_bytes_(max_bytes), max_models_(max_models) {}

ModelStore::AddResult ModelStore::add(const std::string& id, const std::string& name,
                                      std::shared_ptr<const TriangleModel> model, bool pinned) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& held : pinned_) {
    if (held->id == id) return {Outcome::AlreadyHeld, held};
    if (!name.empty() && held->name == name) return {Outcome::NameTaken, nullptr};
  }
  if (auto* entry = uploads_.find(id)) {
    // An upload named later by the folder stays an upload: names are the
    // folder's, given at start, before anything is uploaded.
    return {Outcome::AlreadyHeld, entry->value};
  }
  auto held = std::make_shared<HeldModel>();
  held->id = id;
  held->name = name;
  held->pinned = pinned;
  held->bytes = model->bytes();
  held->model = std::move(model);
  // What is left for this model once every upload is dropped.
  const std::uint64_t room = max_bytes_ - pinned_bytes_;
  const std::size_t slots = max_models_ - pinned_.size();
  if (held->bytes > room || slots == 0) return {Outcome::TooLarge, nullptr};
  if (pinned) {
    pinned_.push_back(held);
    pinned_bytes_ += held->bytes;
    std::sort(pinned_.begin(), pinned_.end(), [](const auto& a, const auto& b) { return a->name < b->name; });
    uploads_.evict_to(max_bytes_ - pinned_bytes_, max_models_ - pinned_.size());
  } else {
    uploads_.insert(id, held, held->bytes);
    uploads_.evict_to(room, slots, 1);
  }
  return {Outcome::Added, held};
}

std::shared_ptr<const HeldModel> ModelStore::find(const std::string& id_or_name) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& held : pinned_)
    if (held->id == id_or_name || held->name == id_or_name) return held;
  if (auto* entry = uploads_.find(id_or_name)) return entry->value;
  return nullptr;
}

std::vector<std::shared_ptr<const HeldModel>> ModelStore::list() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::shared_ptr<const HeldModel>> out = pinned_;
  uploads_.for_each([&](const auto& entry) { out.push_back(entry.value); });
  return out;
}

std::size_t ModelStore::count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pinned_.size() + uploads_.size();
}

std::uint64_t ModelStore::bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pinned_bytes_ + uploads_.bytes();
}

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool valid_model_name(const std::string& name) {
  return !name.empty() && name.size() <= 128 && std::all_of(name.begin(), name.end(), [](char c) {
           return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-';
         });
}

}  // namespace

bool load_model_folder(const std::string& folder, ModelStore& store, std::size_t max_file_bytes, FolderLoad& result,
                       std::string& error) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<fs::path> files;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string extension = lower(it->path().extension().string());
    if (extension == ".glb" || extension == ".gltf") files.push_back(it->path());
  }
  if (ec) {
    error = "cannot read the folder '" + folder + "': " + ec.message();
    return false;
  }
  std::sort(files.begin(), files.end());
  LoadOptions options;
  options.external_folder = folder;
  options.max_external_bytes = max_file_bytes;
  for (const fs::path& path : files) {
    const std::string file = path.filename().string();
    const std::string name = path.stem().string();
    const auto refuse = [&](const std::string& why) { result.refused.push_back(file + ": " + why); };
    if (!valid_model_name(name)) {
      refuse("a model's name (the file name without extension) must be 1 to 128 of A-Z a-z 0-9 . _ -");
      continue;
    }
    // The file itself must lie inside the folder too (not a symlink out).
    char* root = realpath(folder.c_str(), nullptr);
    char* real = realpath(path.c_str(), nullptr);
    const std::string root_path = root ? root : "", real_path = real ? real : "";
    std::free(root);
    std::free(real);
    if (root_path.empty() || real_path.compare(0, root_path.size() + 1, root_path + "/") != 0) {
      refuse("its real path lies outside the folder");
      continue;
    }
    const auto size = fs::file_size(real_path, ec);
    if (ec || !fs::is_regular_file(real_path, ec)) {
      refuse("not a readable regular file");
      continue;
    }
    if (size > max_file_bytes) {
      refuse(std::to_string(size) + " bytes, more than the " + std::to_string(max_file_bytes >> 20) +
             " MiB a model may have (--max-model-mib)");
      continue;
    }
    std::ifstream in(real_path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (bytes.size() > max_file_bytes) bytes.resize(max_file_bytes);  // grew since it was measured
    options.format = lower(path.extension().string()) == ".glb" ? LoadOptions::Format::Binary : LoadOptions::Format::Json;
    LoadResult loaded = load_gltf(bytes, options);
    if (!loaded.ok()) {
      refuse(loaded.error);
      continue;
    }
    const ModelStore::AddResult added = store.add(model_id_for(bytes), name, std::move(loaded.model), true);
    switch (added.outcome) {
      case ModelStore::Outcome::Added: result.loaded.push_back(added.held); break;
      case ModelStore::Outcome::AlreadyHeld: refuse("the same bytes as the model '" + added.held->name + "'"); break;
      case ModelStore::Outcome::NameTaken: refuse("another file already gave a model the name '" + name + "'"); break;
      case ModelStore::Outcome::TooLarge: refuse("over the models' memory budget (--models-budget-mib)"); break;
    }
  }
  return true;
}

void hold_builtin_models(ModelStore& store, std::vector<std::string>& not_held) {
  for (const BuiltinModel& builtin : builtin_models()) {
    ModelStore::AddResult added = store.add(builtin.id, builtin.name, builtin.model, true);
    if (added.outcome == ModelStore::Outcome::NameTaken) {
      // Still listed, by id alone: the operator's own model has the name.
      added = store.add(builtin.id, "", builtin.model, true);
      not_held.push_back("built-in model " + builtin.name + ": the name is taken by a --models file; it is listed by id");
    }
    if (added.outcome == ModelStore::Outcome::TooLarge)
      not_held.push_back("built-in model " + builtin.name + ": over --models-budget-mib; not listed");
  }
}

}  // namespace umbra
