#include "model_archive.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "model.hpp"

namespace umbra {

namespace {

const char* extension(LoadOptions::Format format) { return format == LoadOptions::Format::Json ? ".gltf" : ".glb"; }

std::string hex_of(const std::string& id) { return id.substr(7); }

bool exists(const std::string& path) {
  struct stat info {};
  return stat(path.c_str(), &info) == 0 && S_ISREG(info.st_mode);
}

}  // namespace

bool is_model_id(std::string_view id) {
  if (id.size() != 7 + 64 || id.substr(0, 7) != "sha256:") return false;
  for (char c : id.substr(7))
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
}

ModelArchive::ModelArchive(std::string folder) : folder_(std::move(folder)) {}

bool ModelArchive::save(const std::string& id, LoadOptions::Format format, std::string_view body,
                        std::string& why) const {
  if (!is_model_id(id)) {
    why = "not a model id";
    return false;
  }
  const std::string path = folder_ + "/" + hex_of(id) + extension(format);
  if (exists(path)) return true;  // content-addressed: the same bytes are there
  // A name no reader looks for (it starts with a dot), unique to this write.
  std::random_device random;
  const std::string temporary = folder_ + "/.upload-" + hex_of(id).substr(0, 16) + "-" +
                                std::to_string(random()) + "-" + std::to_string(getpid());
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    why = "cannot create a file in " + folder_ + ": " + std::strerror(errno);
    return false;
  }
  std::size_t written = 0;
  while (written < body.size()) {
    const ssize_t n = ::write(fd, body.data() + written, body.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    written += std::size_t(n);
  }
  // On disk before it gets its name: a crash leaves a stray temporary file,
  // never a named one cut short.
  const bool complete = written == body.size() && ::fsync(fd) == 0;
  const int write_errno = errno;
  ::close(fd);
  if (!complete || std::rename(temporary.c_str(), path.c_str()) != 0) {
    why = "cannot write " + path + ": " + std::strerror(complete ? errno : write_errno);
    std::remove(temporary.c_str());
    return false;
  }
  return true;
}

std::optional<ModelArchive::Stored> ModelArchive::load(const std::string& id, std::size_t max_bytes,
                                                       std::string& why) const {
  if (!is_model_id(id)) return std::nullopt;
  for (LoadOptions::Format format : {LoadOptions::Format::Binary, LoadOptions::Format::Json}) {
    const std::string path = folder_ + "/" + hex_of(id) + extension(format);
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
    return stored;
  }
  return std::nullopt;
}

}  // namespace umbra
