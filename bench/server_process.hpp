// The real umbra-server binary as a child process, for what only a process
// shows: signals, exit status, resident memory.
#pragma once

#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <sys/types.h>

namespace umbra::testing {

class ServerProcess {
 public:
  /// Starts `binary --port 0 args...` and waits until it listens (throws
  /// std::runtime_error with its log if it exits first).
  ServerProcess(const std::string& binary, const std::vector<std::string>& args);
  /// Kills it (SIGKILL) if it is still running.
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  void send_signal(int signal) const;
  /// Waits for it to end: its exit code, or 128 + the signal that killed it.
  int wait();
  /// Resident memory (VmRSS), KiB; -1 if unknown.
  long resident_kib() const;
  /// Everything it wrote to stderr so far (complete after wait()).
  std::string log() const;

 private:
  pid_t pid_ = -1;
  int port_ = 0;
  int exit_code_ = -1;
  int stderr_fd_ = -1;
  std::thread reader_;
  std::string log_;
  mutable std::mutex log_mutex_;
};

/// "CPU model, N cores, Linux release": the machine a benchmark ran on.
std::string machine_summary();

}  // namespace umbra::testing
