#include "assets/model_store.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <utility>

#include "core/builtin_models.hpp"
#include "assets/gltf_loader.hpp"

namespace umbra {

std::uint64_t max_loaded_bytes(std::uint64_t body_bytes) { return kUploadExpansion * body_bytes + kUploadAllowance; }

std::shared_ptr<const TriangleModel> drawn_model(const std::shared_ptr<const HeldModel>& held) {
  if (!held) return nullptr;
  return std::shared_ptr<const TriangleModel>(held, held->model.get());
}

namespace {

ModelStore::Limits whole_budget(std::uint64_t max_bytes, std::size_t max_models) {
  ModelStore::Limits limits;
  limits.max_bytes = max_bytes;
  limits.max_models = max_models;
  return limits;
}

}  // namespace

ModelStore::ModelStore(std::uint64_t max_bytes, std::size_t max_models)
    : ModelStore(whole_budget(max_bytes, max_models)) {}

ModelStore::ModelStore(const Limits& limits) : limits_(limits), now_([] { return Clock::now(); }) {
  if (limits_.share_bytes == 0 || limits_.share_bytes > limits_.max_bytes) limits_.share_bytes = limits_.max_bytes;
  // The same fraction of the count: many tiny models must not evict others' either.
  const long double fraction = limits_.max_bytes ? (long double)limits_.share_bytes / limits_.max_bytes : 1.0L;
  share_models_ = std::max<std::size_t>(1, std::size_t(fraction * limits_.max_models));
}

ModelStore::~ModelStore() = default;

void ModelStore::set_clock(std::function<Clock::time_point()> now) {
  std::lock_guard<std::mutex> lock(mutex_);
  now_ = std::move(now);
}

// --- Reservations ----------------------------------------------------------

ModelStore::Reservation::Reservation(Reservation&& other) noexcept
    : store_(other.store_), owner_(std::move(other.owner_)), bytes_(other.bytes_) {
  other.store_ = nullptr;
  other.bytes_ = 0;
}

ModelStore::Reservation& ModelStore::Reservation::operator=(Reservation&& other) noexcept {
  if (this != &other) {
    release();
    store_ = other.store_;
    owner_ = std::move(other.owner_);
    bytes_ = other.bytes_;
    other.store_ = nullptr;
    other.bytes_ = 0;
  }
  return *this;
}

ModelStore::Reservation::~Reservation() { release(); }

void ModelStore::Reservation::release() {
  if (store_ == nullptr) return;
  std::lock_guard<std::mutex> lock(store_->mutex_);
  store_->reserved_ -= bytes_;
  bytes_ = 0;
  store_ = nullptr;
}

std::uint64_t ModelStore::live_locked() const { return alive_->load() + reserved_; }

// Which limit `bytes` of one owner's models can never fit under, if any.
ModelStore::Room ModelStore::limit_for(std::uint64_t bytes) const {
  const std::uint64_t for_uploads = upload_max_bytes_locked();
  if (bytes > limits_.share_bytes && limits_.share_bytes < for_uploads) return Room::OverShare;
  if (bytes > for_uploads) return Room::OverBudget;
  return Room::Made;
}

// What `owner` may drop: its own; another owner's while that owner holds
// more than its share; anything idle for idle_drop. Never a model a render
// is drawing: dropping it would free nothing until the render ends.
bool ModelStore::may_drop(const Upload& upload, const std::string& owner, Clock::time_point now) const {
  if (upload.held.use_count() > 1) return false;
  const std::string& of = upload.held->owner;
  if (of == owner) return true;
  const auto usage = owners_.find(of);
  if (usage != owners_.end() && (usage->second.bytes > limits_.share_bytes || usage->second.count > share_models_))
    return true;
  return now - upload.used >= limits_.idle_drop;
}

void ModelStore::drop(std::list<Upload>::iterator it) {
  const auto& held = *it->held;
  Usage& usage = owners_[held.owner];
  usage.bytes -= held.bytes;
  usage.count -= 1;
  if (usage.count == 0) owners_.erase(held.owner);
  upload_bytes_ -= held.bytes;
  by_id_.erase(held.id);
  uploads_.erase(it);  // the last reference, unless a render holds one: then it stays counted (alive_)
}

bool ModelStore::drop_until(const std::string& owner, const std::function<bool()>& fits) {
  const Clock::time_point now = now_();
  // One pass from the least recently used, each upload judged when it is
  // reached: one passed over stays undroppable, since a drop can only end
  // an owner's over-share, never start one.
  auto candidate = uploads_.end();
  while (!fits()) {
    if (candidate == uploads_.begin()) return false;
    --candidate;
    if (!may_drop(*candidate, owner, now)) continue;
    const auto newer = std::next(candidate);
    drop(candidate);
    candidate = newer;
  }
  return true;
}

ModelStore::Room ModelStore::make_room(const std::string& owner, std::uint64_t bytes) {
  const Room never = limit_for(bytes);
  if (never != Room::Made) return never;
  const auto fits = [&] { return live_locked() + bytes <= limits_.max_bytes; };
  return drop_until(owner, fits) ? Room::Made : Room::NoRoomNow;
}

ModelStore::RoomResult ModelStore::reserve(const std::string& owner, std::uint64_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  RoomResult result;
  result.outcome = make_room(owner, bytes);
  if (result.outcome != Room::Made) return result;
  reserved_ += bytes;
  result.reservation.store_ = this;
  result.reservation.owner_ = owner;
  result.reservation.bytes_ = bytes;
  return result;
}

ModelStore::Room ModelStore::grow(Reservation& reservation, std::uint64_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (reservation.store_ != this) return Room::NoRoomNow;
  if (bytes <= reservation.bytes_) return Room::Made;
  const std::uint64_t more = bytes - reservation.bytes_;
  // The whole of it must fit the limits; the room is made for what is new.
  const Room never = limit_for(bytes);
  if (never != Room::Made) return never;
  const auto fits = [&] { return live_locked() + more <= limits_.max_bytes; };
  if (!drop_until(reservation.owner_, fits)) return Room::NoRoomNow;
  reserved_ += more;
  reservation.bytes_ = bytes;
  return Room::Made;
}

// --- Holding ---------------------------------------------------------------

std::shared_ptr<const HeldModel> ModelStore::make_held(const std::string& id, const std::string& name, bool pinned,
                                                       const std::string& owner,
                                                       std::shared_ptr<const TriangleModel> model) {
  auto* held = new HeldModel;
  held->id = id;
  held->name = name;
  held->pinned = pinned;
  held->owner = owner;
  held->bytes = model->bytes();
  held->model = std::move(model);
  alive_->fetch_add(held->bytes);
  // Counted until the last holder lets go, the store or a render.
  std::shared_ptr<std::atomic<std::uint64_t>> alive = alive_;
  return std::shared_ptr<const HeldModel>(held, [alive](const HeldModel* h) {
    alive->fetch_sub(h->bytes);
    delete h;
  });
}

void ModelStore::touch(std::list<Upload>::iterator it) {
  it->used = now_();
  uploads_.splice(uploads_.begin(), uploads_, it);
}

ModelStore::AddResult ModelStore::add_upload(const std::string& id, std::shared_ptr<const TriangleModel> model,
                                             Reservation& room) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& held : pinned_)
      if (held->id == id) return {Outcome::AlreadyHeld, held};
    if (const auto found = by_id_.find(id); found != by_id_.end()) {
      touch(found->second);
      return {Outcome::AlreadyHeld, uploads_.front().held};
    }
  }
  const std::uint64_t bytes = model->bytes();
  if (room.bytes_ < bytes) {
    const Room grown = grow(room, bytes);
    if (grown == Room::OverBudget || grown == Room::OverShare) return {Outcome::TooLarge, nullptr};
    if (grown != Room::Made) return {Outcome::NoRoom, nullptr};
  }
  std::lock_guard<std::mutex> lock(mutex_);
  if (const auto found = by_id_.find(id); found != by_id_.end()) {  // added meanwhile
    touch(found->second);
    return {Outcome::AlreadyHeld, uploads_.front().held};
  }
  const std::string& owner = room.owner_;
  const auto count_fits = [&] { return pinned_.size() + uploads_.size() < limits_.max_models; };
  if (!drop_until(owner, count_fits)) return {Outcome::NoRoom, nullptr};
  // The reservation's bytes become the model's (alive_ counts them now).
  auto held = make_held(id, "", false, owner, std::move(model));
  room.bytes_ -= bytes;
  reserved_ -= bytes;
  uploads_.push_front(Upload{held, now_()});
  by_id_[id] = uploads_.begin();
  upload_bytes_ += bytes;
  Usage& usage = owners_[owner];
  usage.bytes += bytes;
  usage.count += 1;
  return {Outcome::Added, held};
}

ModelStore::AddResult ModelStore::add(const std::string& id, const std::string& name,
                                      std::shared_ptr<const TriangleModel> model, bool pinned) {
  if (!pinned) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (const auto found = by_id_.find(id); found != by_id_.end()) {
        touch(found->second);
        return {Outcome::AlreadyHeld, uploads_.front().held};
      }
      for (const auto& held : pinned_)
        if (held->id == id) return {Outcome::AlreadyHeld, held};
    }
    RoomResult room = reserve("", model->bytes());
    if (room.outcome == Room::NoRoomNow) return {Outcome::NoRoom, nullptr};
    if (room.outcome != Room::Made) return {Outcome::TooLarge, nullptr};
    return add_upload(id, std::move(model), room.reservation);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& held : pinned_) {
    if (held->id == id) return {Outcome::AlreadyHeld, held};
    if (!name.empty() && held->name == name) return {Outcome::NameTaken, nullptr};
  }
  if (const auto found = by_id_.find(id); found != by_id_.end()) {
    // An upload named later by the folder stays an upload: names are the
    // folder's, given at start, before anything is uploaded.
    return {Outcome::AlreadyHeld, found->second->held};
  }
  const std::uint64_t bytes = model->bytes();
  if (bytes > upload_max_bytes_locked() || pinned_.size() >= limits_.max_models)
    return {Outcome::TooLarge, nullptr};
  auto held = make_held(id, name, true, "", std::move(model));
  pinned_.push_back(held);
  pinned_bytes_ += bytes;
  std::sort(pinned_.begin(), pinned_.end(), [](const auto& a, const auto& b) { return a->name < b->name; });
  // The operator's models come first (they are added at start): uploads go.
  while (!uploads_.empty() && (pinned_bytes_ + upload_bytes_ > limits_.max_bytes ||
                               pinned_.size() + uploads_.size() > limits_.max_models))
    drop(std::prev(uploads_.end()));
  return {Outcome::Added, held};
}

bool ModelStore::remove_upload(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto found = by_id_.find(id);
  if (found == by_id_.end()) return false;
  drop(found->second);
  return true;
}

std::shared_ptr<const HeldModel> ModelStore::find(const std::string& id_or_name) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& held : pinned_)
    if (held->id == id_or_name || held->name == id_or_name) return held;
  const auto found = by_id_.find(id_or_name);
  if (found == by_id_.end()) return nullptr;
  touch(found->second);
  return uploads_.front().held;
}

std::vector<std::shared_ptr<const HeldModel>> ModelStore::list() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::shared_ptr<const HeldModel>> out = pinned_;
  for (const Upload& upload : uploads_) out.push_back(upload.held);
  return out;
}

std::size_t ModelStore::count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pinned_.size() + uploads_.size();
}

std::uint64_t ModelStore::bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pinned_bytes_ + upload_bytes_;
}

std::uint64_t ModelStore::live_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return live_locked();
}

std::uint64_t ModelStore::owner_bytes(const std::string& owner) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto usage = owners_.find(owner);
  return usage == owners_.end() ? 0 : usage->second.bytes;
}

std::uint64_t ModelStore::upload_max_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return upload_max_bytes_locked();
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
      case ModelStore::Outcome::TooLarge:
      case ModelStore::Outcome::NoRoom:  // pinned models never wait for room
        refuse("over the models' memory budget (--models-budget-mib)");
        break;
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
