#include "assets/model_import.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <vector>

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace umbra {

namespace {

constexpr const char* kStated = "as the file states them, applied by Assimp";
constexpr const char* kNone = "none in the file: read as glTF is, Y up and metres (set up and unit when it is not)";

bool equal_ci(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

// The pipes and the child, closed and reaped however import_model ends.
struct Child {
  pid_t pid = -1;
  int in = -1, out = -1, err = -1;
  ~Child() {
    for (int fd : {in, out, err})
      if (fd >= 0) close(fd);
    if (pid > 0) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
};

}  // namespace

const std::vector<ImportFormat>& import_formats() {
  static const std::vector<ImportFormat> formats = {
      {"obj", {"model/obj"}, "Wavefront OBJ", kNone},
      {"stl", {"model/stl", "application/sla"}, "STL", kNone},
      {"ply", {}, "PLY", kNone},
      {"dae", {"model/vnd.collada+xml"}, "COLLADA", kStated},
      {"fbx", {}, "FBX", "the file's UnitScaleFactor and UpAxis, applied here"},
      {"3ds", {"application/x-3ds", "image/x-3ds"}, "3D Studio", kNone},
      {"ifc", {"application/x-step"}, "IFC",
       "metres and Z up as IFC has them, turned to Y up by Assimp"},
  };
  return formats;
}

const ImportFormat* import_format_named(std::string_view name) {
  if (!name.empty() && name.front() == '.') name.remove_prefix(1);
  for (const ImportFormat& f : import_formats()) {
    if (equal_ci(name, f.extension)) return &f;
    for (const char* type : f.media_types)
      if (equal_ci(name, type)) return &f;
  }
  return nullptr;
}

std::string default_importer_path() {
  char path[4096];
  const ssize_t n = readlink("/proc/self/exe", path, sizeof path - 1);
  if (n <= 0) return "umbra-model-import";
  std::string self(path, std::size_t(n));
  return self.substr(0, self.rfind('/') + 1) + "umbra-model-import";
}

ImportResult import_model(std::string_view bytes, const ImportFormat& format, const ImportOptions& options) {
  ImportResult result;
  const auto refuse = [&](int status, std::string why) {
    result.status = status;
    result.error = std::move(why);
    result.glb.clear();
    return result;
  };
  int in[2], out[2], err[2];
  if (pipe2(in, O_CLOEXEC) != 0) return refuse(503, "cannot start the model importer (pipe)");
  if (pipe2(out, O_CLOEXEC) != 0) {
    close(in[0]), close(in[1]);
    return refuse(503, "cannot start the model importer (pipe)");
  }
  if (pipe2(err, O_CLOEXEC) != 0) {
    close(in[0]), close(in[1]), close(out[0]), close(out[1]);
    return refuse(503, "cannot start the model importer (pipe)");
  }
  Child child;
  child.in = in[1], child.out = out[0], child.err = err[0];
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, in[0], 0);
  posix_spawn_file_actions_adddup2(&actions, out[1], 1);
  posix_spawn_file_actions_adddup2(&actions, err[1], 2);
  const std::string memory = std::to_string(options.max_memory_mib), seconds = std::to_string(options.max_seconds);
  std::vector<std::string> args = {options.importer, format.extension, "--up", options.up, "--unit", options.unit,
                                   "--max-mib", memory, "--max-seconds", seconds};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  // posix_spawn, not fork: safe in a server with many threads.
  const int spawned = posix_spawn(&child.pid, options.importer.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(in[0]), close(out[1]), close(err[1]);
  if (spawned != 0) {
    child.pid = -1;
    return refuse(503, "the model importer (" + options.importer + ") cannot be run: " + std::strerror(spawned));
  }
  fcntl(child.in, F_SETFL, O_NONBLOCK);
  // A child that stops reading its input must not end this process with
  // SIGPIPE: blocked in this thread while it writes, and any raised taken.
  struct PipeSignalBlocked {
    sigset_t set, old;
    PipeSignalBlocked() {
      sigemptyset(&set);
      sigaddset(&set, SIGPIPE);
      pthread_sigmask(SIG_BLOCK, &set, &old);
    }
    ~PipeSignalBlocked() {
      const timespec none{0, 0};
      while (sigtimedwait(&set, nullptr, &none) > 0) {
      }
      pthread_sigmask(SIG_SETMASK, &old, nullptr);
    }
  } pipe_signal_blocked;

  // Feed the file, gather the .glb and the message, until the child ends
  // or the wall-clock limit (its CPU limit, and as much again) passes.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2 * options.max_seconds + 1);
  auto next_stop_check = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  std::size_t written = 0;
  std::string message;
  bool over = false;
  while (child.out >= 0 || child.err >= 0) {
    pollfd fds[3];
    int n = 0;
    if (child.in >= 0) fds[n++] = {child.in, POLLOUT, 0};
    if (child.out >= 0) fds[n++] = {child.out, POLLIN, 0};
    if (child.err >= 0) fds[n++] = {child.err, POLLIN, 0};
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return refuse(422, std::string("the ") + format.name + " file took longer than " +
                                                  std::to_string(2 * options.max_seconds) + " s to read");
    if (poll(fds, nfds_t(n), int(std::min<long long>(left.count(), 1000))) < 0 && errno != EINTR)
      return refuse(503, "the model importer could not be watched");
    if (options.stop && std::chrono::steady_clock::now() >= next_stop_check) {
      next_stop_check = std::chrono::steady_clock::now() + std::chrono::seconds(1);
      if (options.stop()) return refuse(499, "stopped: the client has gone");
    }
    for (int i = 0; i < n; ++i) {
      if (!fds[i].revents) continue;
      if (fds[i].fd == child.in) {
        const ssize_t w = write(child.in, bytes.data() + written, bytes.size() - written);
        if (w > 0) written += std::size_t(w);
        if (w < 0 && errno != EAGAIN && errno != EINTR) written = bytes.size();  // it stopped reading
        if (written == bytes.size()) close(child.in), child.in = -1;
        continue;
      }
      char chunk[65536];
      const ssize_t r = read(fds[i].fd, chunk, sizeof chunk);
      if (r < 0 && (errno == EAGAIN || errno == EINTR)) continue;
      if (r <= 0) {
        (fds[i].fd == child.out ? child.out : child.err) = -1;
        close(fds[i].fd);
        continue;
      }
      if (fds[i].fd == child.err) {
        if (message.size() < 4096) message.append(chunk, std::size_t(r));
      } else if (result.glb.size() + std::size_t(r) > options.max_output_bytes) {
        over = true;
        kill(child.pid, SIGKILL);
      } else {
        result.glb.append(chunk, std::size_t(r));
      }
    }
  }
  int status = 0;
  waitpid(child.pid, &status, 0);
  child.pid = -1;
  while (!message.empty() && (message.back() == '\n' || message.back() == '\r')) message.pop_back();
  if (message.size() > 300) message = message.substr(0, 300) + "...";
  if (over)
    return refuse(422, std::string("the ") + format.name + " file converts to more than " +
                           std::to_string(options.max_output_bytes >> 20) + " MiB of glTF");
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    if (sig == SIGXCPU || sig == SIGKILL)
      return refuse(422, std::string("the ") + format.name + " file took more than " +
                             std::to_string(options.max_seconds) + " s of CPU to read");
    // Out of its address space (a failed allocation aborts), or a crash.
    return refuse(422, std::string("the ") + format.name + " file could not be read within " +
                           std::to_string(options.max_memory_mib) + " MiB (the importer stopped: signal " +
                           std::to_string(sig) + ")");
  }
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (code == 2) return refuse(400, std::string("not a ") + format.name + " file Assimp can read: " + message);
  if (code == 4) return refuse(422, std::string("the ") + format.name + " file has no triangles: " + message);
  if (code == 5)
    return refuse(422, std::string("the ") + format.name + " file could not be read within " +
                           std::to_string(options.max_memory_mib) + " MiB (" + message + ")");
  if (code != 0) return refuse(503, "the model importer failed (" + std::to_string(code) + "): " + message);
  if (result.glb.empty()) return refuse(400, std::string("the ") + format.name + " file holds nothing to convert");
  return result;
}

unsigned import_cpu_seconds(std::uint64_t bytes, unsigned ceiling) {
  const std::uint64_t seconds = 5 + 2 * (bytes >> 20);
  return unsigned(std::min<std::uint64_t>(seconds, ceiling));
}

}  // namespace umbra
