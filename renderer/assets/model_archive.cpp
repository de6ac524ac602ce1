#include "assets/model_archive.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>
#include <vector>

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "core/model.hpp"
#include "assets/model_store.hpp"

namespace umbra {

namespace {

const char* extension(LoadOptions::Format format) { return format == LoadOptions::Format::Json ? ".gltf" : ".glb"; }

std::string hex_of(const std::string& id) { return id.substr(7); }

bool regular_file(const std::string& path, struct stat& info) {
  return stat(path.c_str(), &info) == 0 && S_ISREG(info.st_mode);
}

bool hex64(std::string_view s) {
  return s.size() == 64 && std::all_of(s.begin(), s.end(), [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

// A unique temporary name in `folder`: it starts with a dot, so no reader
// looks for it, and eviction knows it for a write under way (or a crash's).
std::string temporary_name(const std::string& folder, const std::string& hint) {
  std::random_device random;
  return folder + "/.upload-" + hint.substr(0, 16) + "-" + std::to_string(random()) + "-" + std::to_string(getpid());
}

bool disk_full(int error) { return error == ENOSPC || error == EDQUOT || error == EFBIG; }

std::string record_text(const ModelArchive::Record& record) {
  return nlohmann::json{{"bytes_bound", record.bytes_bound}, {"triangles", record.triangles}, {"owner", record.owner}}
             .dump() +
         "\n";
}

std::optional<ModelArchive::Record> parse_record(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::string text(4096, '\0');
  in.read(text.data(), std::streamsize(text.size()));
  text.resize(std::size_t(in.gcount()));
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (!j.is_object() || !j.contains("bytes_bound") || !j["bytes_bound"].is_number_unsigned() ||
      !j.contains("triangles") || !j["triangles"].is_number_unsigned())
    return std::nullopt;  // not ours, or cut short: as if there were none
  ModelArchive::Record record{j["bytes_bound"].get<std::uint64_t>(), j["triangles"].get<std::uint64_t>(), ""};
  // Written by an older server: no owner, anonymous.
  if (j.contains("owner") && j["owner"].is_string()) record.owner = j["owner"].get<std::string>();
  return record;
}

std::int64_t mtime_ns_of(const struct stat& info) {
  return std::int64_t(info.st_mtim.tv_sec) * 1000000000 + info.st_mtim.tv_nsec;
}

// What a file takes on disk: its allocated blocks, not its length.
std::uint64_t allocated_bytes(const struct stat& info) { return std::uint64_t(info.st_blocks) * 512; }

// What a file of `bytes` will take on disk, before it is written: whole
// 4 KiB blocks (the common block size; a file system with smaller ones
// makes this an overestimate, so never less room than needed).
std::uint64_t allocated_estimate(std::uint64_t bytes) { return (bytes + 4095) / 4096 * 4096; }

}  // namespace

bool is_model_id(std::string_view id) { return id.size() == 7 + 64 && id.substr(0, 7) == "sha256:" && hex64(id.substr(7)); }

ModelArchive::ModelArchive(std::string folder, std::uint64_t max_bytes)
    : ModelArchive(std::move(folder), Limits{max_bytes}) {}

ModelArchive::ModelArchive(std::string folder, const Limits& limits) : folder_(std::move(folder)), limits_(limits) {
  limits_.max_files = std::max<std::uint64_t>(limits_.max_files, 1);
}

std::string ModelArchive::model_path(const std::string& id, LoadOptions::Format format) const {
  return folder_ + "/" + hex_of(id) + extension(format);
}

std::string ModelArchive::record_path(const std::string& hex) const { return folder_ + "/" + hex + ".json"; }

bool ModelArchive::write_file(const std::string& path, std::string_view data, int& error) {
  const std::string temporary = temporary_name(folder_, path.substr(folder_.size() + 1));
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    error = errno;
    return false;
  }
  std::size_t written = 0;
  error = 0;
  while (written < data.size()) {
    const ssize_t n = write_for_test ? write_for_test(fd, data.data() + written, data.size() - written)
                                     : ::write(fd, data.data() + written, data.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = n < 0 ? errno : ENOSPC;
      break;
    }
    written += std::size_t(n);
  }
  // On disk before it gets its name: a crash leaves a stray temporary file,
  // never a named one cut short.
  if (error == 0 && ::fsync(fd) != 0) error = errno;
  ::close(fd);
  if (error == 0 && std::rename(temporary.c_str(), path.c_str()) != 0) error = errno;
  if (error != 0) std::remove(temporary.c_str());
  return error == 0;
}

// One model of the folder, as eviction sees it.
struct ModelArchive::Scan {
  struct Model {
    std::string name;  // "<hex>.glb" or "<hex>.gltf"
    std::uint64_t bytes = 0;  // allocated, its record's included
    std::int64_t mtime_ns = 0;
    std::string owner;
    bool has_record = false;
  };
  std::vector<Model> models;
  std::uint64_t total = 0;  // allocated bytes of every file counted
};

ModelArchive::Scan ModelArchive::scan() {
  struct RecordFile {
    std::uint64_t bytes = 0;
    std::uint64_t inode = 0;
    std::int64_t mtime_ns = 0;
  };
  Scan result;
  std::unordered_map<std::string, RecordFile> records;  // by hex
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const std::int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
  const std::int64_t stray_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(kStrayAfter).count();
  DIR* dir = opendir(folder_.c_str());
  if (dir == nullptr) {
    result.total = bytes_on_disk_.load();
    return result;
  }
  while (const dirent* e = readdir(dir)) {
    const std::string name = e->d_name;
    if (name == "." || name == "..") continue;
    struct stat info {};
    if (fstatat(dirfd(dir), name.c_str(), &info, AT_SYMLINK_NOFOLLOW) != 0 || !S_ISREG(info.st_mode)) continue;
    const std::int64_t mtime_ns = mtime_ns_of(info);
    const std::uint64_t bytes = allocated_bytes(info);
    const std::string stem = name.substr(0, name.find('.'));
    const std::string suffix = name.size() > 64 ? name.substr(64) : "";
    if (name.rfind(".upload-", 0) == 0) {
      // Another write under way (counted), or a crash's leftover (deleted).
      if (now_ns - mtime_ns > stray_ns && ::unlink((folder_ + "/" + name).c_str()) == 0) continue;
      result.total += bytes;
    } else if (hex64(stem) && (suffix == ".glb" || suffix == ".gltf")) {
      result.models.push_back({name, bytes, mtime_ns, "", false});
      result.total += bytes;
    } else if (hex64(stem) && suffix == ".json") {
      records[stem] = {bytes, std::uint64_t(info.st_ino), mtime_ns};
      result.total += bytes;
    }
    // Anything else is not ours: neither counted nor touched.
  }
  closedir(dir);
  // Each model with its record (a hash lookup: one scan is linear), the
  // owner read from it once per record file.
  std::unordered_map<std::string, KnownOwner> owners;
  owners.reserve(result.models.size());
  for (Scan::Model& model : result.models) {
    const std::string hex = model.name.substr(0, 64);
    const auto record = records.find(hex);
    if (record == records.end()) continue;  // anonymous
    model.has_record = true;
    model.bytes += record->second.bytes;
    const auto known = owners_.find(hex);
    if (known != owners_.end() && known->second.inode == record->second.inode &&
        known->second.mtime_ns == record->second.mtime_ns) {
      model.owner = known->second.owner;
    } else {
      const std::optional<Record> parsed = parse_record(record_path(hex));
      model.owner = parsed ? parsed->owner : "";
    }
    owners[hex] = {record->second.inode, record->second.mtime_ns, model.owner};
    records.erase(record);
  }
  owners_ = std::move(owners);  // what the folder holds now: bounded by it
  // Records whose model is gone (evicted by another server meanwhile, or
  // the model's write still under way: only old ones).
  for (const auto& [hex, record] : records)
    if (now_ns - record.mtime_ns > stray_ns && ::unlink(record_path(hex).c_str()) == 0)
      result.total -= std::min(result.total, record.bytes);
  return result;
}

bool ModelArchive::evict_to(const std::string& owner, std::uint64_t max_total, std::uint64_t max_models) {
  std::lock_guard<std::mutex> lock(scan_mutex_);
  Scan folder = scan();
  std::uint64_t total = folder.total, models = folder.models.size();
  const auto fits = [&] { return total <= max_total && models <= max_models; };
  if (fits()) {
    bytes_on_disk_.store(total);
    return true;
  }
  struct Usage {
    std::uint64_t bytes = 0, files = 0;
  };
  std::unordered_map<std::string, Usage> usage;
  for (const Scan::Model& model : folder.models) {
    usage[model.owner].bytes += model.bytes;
    usage[model.owner].files += 1;
  }
  const std::uint64_t share_bytes = limits_.share_bytes ? limits_.share_bytes : limits_.max_bytes;
  const std::uint64_t share_files = limits_.share_files ? limits_.share_files : limits_.max_files;
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const std::int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
  const std::int64_t idle_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(limits_.idle_delete).count();
  // Least recently used first (ties: by name, so that servers agree). One
  // pass: a deletion only shrinks an owner's use, so a file skipped never
  // becomes one this owner may delete.
  std::sort(folder.models.begin(), folder.models.end(), [](const Scan::Model& a, const Scan::Model& b) {
    return a.mtime_ns != b.mtime_ns ? a.mtime_ns < b.mtime_ns : a.name < b.name;
  });
  std::vector<const Scan::Model*> chosen;
  for (const Scan::Model& model : folder.models) {
    if (fits()) break;
    Usage& of = usage[model.owner];
    const bool may = model.owner == owner || of.bytes > share_bytes || of.files > share_files ||
                     now_ns - model.mtime_ns > idle_ns;
    if (!may) continue;
    chosen.push_back(&model);
    of.bytes -= std::min(of.bytes, model.bytes);
    of.files -= 1;
    total -= std::min(total, model.bytes);
    models -= 1;
  }
  if (!fits()) {  // deletes nothing: room that would not suffice is not taken from anyone
    bytes_on_disk_.store(folder.total);
    return false;
  }
  for (const Scan::Model* model : chosen) {
    // Gone already (another server evicted it): freed all the same.
    if (::unlink((folder_ + "/" + model->name).c_str()) == 0) evicted_.fetch_add(1);
    if (model->has_record) ::unlink(record_path(model->name.substr(0, 64)).c_str());
  }
  bytes_on_disk_.store(total);
  return true;
}

ModelArchive::Saved ModelArchive::save(const std::string& id, LoadOptions::Format format, std::string_view body,
                                       std::string& why, const std::optional<Record>& record) {
  if (!is_model_id(id)) {
    why = "not a model id";
    return {Status::Failed, ""};
  }
  const std::string path = model_path(id, format);
  struct stat info {};
  if (regular_file(path, info)) {  // content-addressed: the same bytes are there
    ::utimensat(AT_FDCWD, path.c_str(), nullptr, 0);
    if (record) {
      const std::optional<Found> there = find(id);
      if (there && !there->record) write_record(id, *record);
    }
    return {Status::Saved, ""};
  }
  const std::string owner = record ? record->owner : "";
  const std::uint64_t needed =
      allocated_estimate(body.size()) + (record ? allocated_estimate(record_text(*record).size()) : 0);
  if (needed > limits_.max_bytes) {
    why = std::to_string(body.size()) + " bytes (" + std::to_string(needed) + " on disk), more than the " +
          std::to_string(limits_.max_bytes >> 20) + " MiB the model store holds in all (--model-store-max-gib)";
    return {Status::TooLarge, why};
  }
  if (!evict_to(owner, limits_.max_bytes - needed, limits_.max_files - 1)) {
    why = "the model store's " + std::to_string(limits_.max_bytes >> 20) + " MiB and " +
          std::to_string(limits_.max_files) +
          " models (--model-store-max-gib) are held by other clients' models within their share and by writes "
          "under way; retry later";
    return {Status::NoRoomNow, why};
  }
  int error = 0;
  if (!write_file(path, body, error) && disk_full(error)) {
    // The disk is fuller than the bound says (other files, or a smaller
    // volume): free what this write needs beyond what is there, once.
    const std::uint64_t on_disk = bytes_on_disk_.load();
    evict_to(owner, on_disk > needed ? on_disk - needed : 0, limits_.max_files - 1);
    write_file(path, body, error);
  }
  if (error != 0) {
    // The client learns the id and the error; only the log learns the path.
    why = "cannot write the model " + id.substr(0, 19) + "...: " + std::strerror(error);
    return {disk_full(error) ? Status::NoSpace : Status::Failed, "cannot write " + path + ": " + std::strerror(error)};
  }
  bytes_on_disk_.fetch_add(allocated_estimate(body.size()));
  if (record) write_record(id, *record);
  return {Status::Saved, ""};
}

void ModelArchive::write_record(const std::string& id, const Record& record) {
  if (!is_model_id(id)) return;
  // Best effort: without a record, the model is measured when it is loaded.
  int error = 0;
  const std::string text = record_text(record);
  if (write_file(record_path(hex_of(id)), text, error)) bytes_on_disk_.fetch_add(allocated_estimate(text.size()));
}

std::optional<ModelArchive::Found> ModelArchive::find(const std::string& id) const {
  if (!is_model_id(id)) return std::nullopt;
  for (LoadOptions::Format format : {LoadOptions::Format::Binary, LoadOptions::Format::Json}) {
    struct stat info {};
    if (!regular_file(model_path(id, format), info)) continue;
    Found found;
    found.format = format;
    found.file_bytes = std::uint64_t(info.st_size);
    found.record = parse_record(record_path(hex_of(id)));
    if (found.record) found.owner = found.record->owner;
    // A claim no upload of this file could make (a record cut, changed or
    // of another file) is not taken: the loader's own bound is admitted.
    if (found.record && found.record->bytes_bound > max_loaded_bytes(found.file_bytes)) found.record.reset();
    return found;
  }
  return std::nullopt;
}

void ModelArchive::touch(const std::string& id) {
  if (!is_model_id(id)) return;
  const auto now = std::chrono::steady_clock::now();
  {
    std::lock_guard<std::mutex> lock(touched_mutex_);
    auto& last = touched_[id];
    if (last != std::chrono::steady_clock::time_point{} && now - last < kTouchEvery) return;
    last = now;
    if (touched_.size() > 65536) touched_.clear();  // a bound; forgetting only costs a syscall
  }
  for (LoadOptions::Format format : {LoadOptions::Format::Binary, LoadOptions::Format::Json})
    if (::utimensat(AT_FDCWD, model_path(id, format).c_str(), nullptr, 0) == 0) return;
}

std::optional<ModelArchive::Stored> ModelArchive::load(const std::string& id, std::size_t max_bytes, std::string& why) {
  if (!is_model_id(id)) return std::nullopt;
  for (LoadOptions::Format format : {LoadOptions::Format::Binary, LoadOptions::Format::Json}) {
    const std::string path = model_path(id, format);
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) continue;
    struct stat info {};
    if (::fstat(fd, &info) != 0 || !S_ISREG(info.st_mode)) {
      ::close(fd);
      continue;
    }
    Stored stored;
    stored.format = format;
    // Sized by the file, not by the limit: a small model takes a small
    // buffer. One byte past both tells a file that grew meanwhile, or one
    // over the limit, from one of exactly that size.
    stored.body.resize(std::min<std::uint64_t>(std::uint64_t(info.st_size), max_bytes) + 1);
    std::size_t got = 0;
    while (got < stored.body.size()) {
      const ssize_t n = ::read(fd, stored.body.data() + got, stored.body.size() - got);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      got += std::size_t(n);
    }
    ::close(fd);
    stored.body.resize(got);
    if (stored.body.size() > max_bytes) {
      why = path + " is larger than " + std::to_string(max_bytes) + " bytes (--max-model-mib)";
      return std::nullopt;
    }
    if (model_id_for(stored.body) != id) {
      why = path + " does not hash to its name: changed or cut short, so not taken";
      return std::nullopt;
    }
    touch(id);
    return stored;
  }
  return std::nullopt;
}

}  // namespace umbra
