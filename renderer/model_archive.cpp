#include "model_archive.hpp"

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

#include "model.hpp"

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
  return nlohmann::json{{"bytes_bound", record.bytes_bound}, {"triangles", record.triangles}}.dump() + "\n";
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
  return ModelArchive::Record{j["bytes_bound"].get<std::uint64_t>(), j["triangles"].get<std::uint64_t>()};
}

// One file of the folder, as eviction sees it.
struct Entry {
  std::string name;
  std::uint64_t bytes = 0;
  std::int64_t mtime_ns = 0;
};

}  // namespace

bool is_model_id(std::string_view id) { return id.size() == 7 + 64 && id.substr(0, 7) == "sha256:" && hex64(id.substr(7)); }

ModelArchive::ModelArchive(std::string folder, std::uint64_t max_bytes)
    : folder_(std::move(folder)), max_bytes_(max_bytes) {}

std::string ModelArchive::model_path(const std::string& id, LoadOptions::Format format) const {
  return folder_ + "/" + hex_of(id) + extension(format);
}

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

std::uint64_t ModelArchive::evict_to(std::uint64_t max_total) {
  std::vector<Entry> models;
  std::map<std::string, std::uint64_t> records;  // hex -> bytes
  std::uint64_t total = 0;
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const std::int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
  const std::int64_t stray_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(kStrayAfter).count();
  DIR* dir = opendir(folder_.c_str());
  if (dir == nullptr) return bytes_on_disk_.load();
  while (const dirent* e = readdir(dir)) {
    const std::string name = e->d_name;
    if (name == "." || name == "..") continue;
    struct stat info {};
    if (!regular_file(folder_ + "/" + name, info)) continue;
    const std::int64_t mtime_ns = std::int64_t(info.st_mtim.tv_sec) * 1000000000 + info.st_mtim.tv_nsec;
    const std::uint64_t bytes = std::uint64_t(info.st_size);
    const std::string stem = name.substr(0, name.find('.'));
    const std::string suffix = name.size() > 64 ? name.substr(64) : "";
    if (name.rfind(".upload-", 0) == 0) {
      // Another write under way (counted), or a crash's leftover (deleted).
      if (now_ns - mtime_ns > stray_ns && ::unlink((folder_ + "/" + name).c_str()) == 0) continue;
      total += bytes;
    } else if (hex64(stem) && (suffix == ".glb" || suffix == ".gltf")) {
      models.push_back({name, bytes, mtime_ns});
      total += bytes;
    } else if (hex64(stem) && suffix == ".json") {
      records[stem] += bytes;
      total += bytes;
    }
    // Anything else is not ours: neither counted nor touched.
  }
  closedir(dir);
  // Records whose model is gone (evicted by another server meanwhile, or
  // the model's write still under way: only old ones).
  for (const auto& [hex, bytes] : records) {
    const bool has_model = std::any_of(models.begin(), models.end(), [&](const Entry& m) { return m.name.rfind(hex, 0) == 0; });
    struct stat info {};
    const std::string path = folder_ + "/" + hex + ".json";
    if (!has_model && stat(path.c_str(), &info) == 0 &&
        now_ns - (std::int64_t(info.st_mtim.tv_sec) * 1000000000 + info.st_mtim.tv_nsec) > stray_ns &&
        ::unlink(path.c_str()) == 0)
      total -= bytes;
  }
  // Least recently used first (ties: by name, so that servers agree).
  std::sort(models.begin(), models.end(), [](const Entry& a, const Entry& b) {
    return a.mtime_ns != b.mtime_ns ? a.mtime_ns < b.mtime_ns : a.name < b.name;
  });
  for (const Entry& model : models) {
    if (total <= max_total) break;
    const std::string hex = model.name.substr(0, 64);
    // Gone already (another server evicted it): freed all the same.
    if (::unlink((folder_ + "/" + model.name).c_str()) == 0) evicted_.fetch_add(1);
    total -= std::min(total, model.bytes);
    const auto record = records.find(hex);
    if (record != records.end()) {
      ::unlink((folder_ + "/" + hex + ".json").c_str());
      total -= std::min(total, record->second);
    }
  }
  bytes_on_disk_.store(total);
  return total;
}

ModelArchive::Saved ModelArchive::save(const std::string& id, LoadOptions::Format format, std::string_view body,
                                       std::string& why, const std::optional<Record>& record) {
  if (!is_model_id(id)) {
    why = "not a model id";
    return {Status::Failed};
  }
  const std::string path = model_path(id, format);
  struct stat info {};
  if (regular_file(path, info)) {  // content-addressed: the same bytes are there
    ::utimensat(AT_FDCWD, path.c_str(), nullptr, 0);
    if (record) {
      const std::optional<Found> there = find(id);
      if (there && !there->record) write_record(id, *record);
    }
    return {Status::Saved};
  }
  const std::uint64_t record_bytes = record ? record_text(*record).size() : 0;
  const std::uint64_t needed = body.size() + record_bytes;
  if (needed > max_bytes_) {
    why = std::to_string(body.size()) + " bytes, more than the " + std::to_string(max_bytes_ >> 20) +
          " MiB the model store may hold (--model-store-max-gib)";
    return {Status::NoSpace};
  }
  evict_to(max_bytes_ - needed);
  int error = 0;
  if (!write_file(path, body, error) && disk_full(error)) {
    // The disk is fuller than the bound says (other files, or a smaller
    // volume): free what this write needs beyond what is there, once.
    const std::uint64_t on_disk = bytes_on_disk_.load();
    evict_to(on_disk > needed ? on_disk - needed : 0);
    write_file(path, body, error);
  }
  if (error != 0) {
    why = "cannot write " + path + ": " + std::strerror(error);
    return {disk_full(error) ? Status::NoSpace : Status::Failed};
  }
  bytes_on_disk_.fetch_add(body.size());
  if (record) write_record(id, *record);
  return {Status::Saved};
}

void ModelArchive::write_record(const std::string& id, const Record& record) {
  if (!is_model_id(id)) return;
  // Best effort: without a record, the model is measured when it is loaded.
  int error = 0;
  const std::string text = record_text(record);
  if (write_file(folder_ + "/" + hex_of(id) + ".json", text, error)) bytes_on_disk_.fetch_add(text.size());
}

std::optional<ModelArchive::Found> ModelArchive::find(const std::string& id) const {
  if (!is_model_id(id)) return std::nullopt;
  for (LoadOptions::Format format : {LoadOptions::Format::Binary, LoadOptions::Format::Json}) {
    struct stat info {};
    if (!regular_file(model_path(id, format), info)) continue;
    Found found;
    found.format = format;
    found.file_bytes = std::uint64_t(info.st_size);
    found.record = parse_record(folder_ + "/" + hex_of(id) + ".json");
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
    std::ifstream file(path, std::ios::binary);
    if (!file) continue;
    Stored stored;
    stored.format = format;
    // One byte past the limit tells "too large" from "exactly the limit".
    stored.body.resize(max_bytes + 1);
    file.read(stored.body.data(), std::streamsize(stored.body.size()));
    stored.body.resize(std::size_t(file.gcount()));
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
