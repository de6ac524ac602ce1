#include "server_process.hpp"

#include <chrono>
#include <csignal>
#include <fstream>
#include <mutex>
#include <regex>
#include <stdexcept>

#include <sys/utsname.h>
#include <sys/wait.h>
#include <unistd.h>

namespace umbra::testing {

ServerProcess::ServerProcess(const std::string& binary, const std::vector<std::string>& args) {
  int pipe_fds[2];
  if (pipe(pipe_fds) != 0) throw std::runtime_error("pipe failed");
  std::vector<std::string> argv_strings{binary, "--port", "0"};
  argv_strings.insert(argv_strings.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_strings) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_ = fork();
  if (pid_ < 0) throw std::runtime_error("fork failed");
  if (pid_ == 0) {
    dup2(pipe_fds[1], STDERR_FILENO);
    close(pipe_fds[0]);
    close(pipe_fds[1]);
    // The test may block signals in its threads; the server must start clean.
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, nullptr);
    execv(binary.c_str(), argv.data());
    _exit(127);
  }
  close(pipe_fds[1]);
  stderr_fd_ = pipe_fds[0];
  // Read its log on a thread of its own, so that the pipe never fills.
  reader_ = std::thread([this] {
    char buffer[4096];
    for (ssize_t n; (n = read(stderr_fd_, buffer, sizeof buffer)) > 0;) {
      std::lock_guard<std::mutex> lock(log_mutex_);
      log_.append(buffer, std::size_t(n));
    }
  });
  const std::regex listening(R"(listening on http://[^:]+:(\d+)/)");
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < give_up) {
    std::smatch m;
    const std::string text = log();
    if (std::regex_search(text, m, listening)) {
      port_ = std::stoi(m[1]);
      return;
    }
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      pid_ = -1;
      reader_.join();
      throw std::runtime_error("umbra-server exited before listening:\n" + log());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  throw std::runtime_error("umbra-server did not listen within 60 s:\n" + log());
}

ServerProcess::~ServerProcess() {
  if (pid_ > 0) {
    kill(pid_, SIGKILL);
    wait();
  }
  if (reader_.joinable()) reader_.join();
  if (stderr_fd_ >= 0) close(stderr_fd_);
}

void ServerProcess::send_signal(int signal) const {
  if (pid_ > 0) kill(pid_, signal);
}

int ServerProcess::wait() {
  if (pid_ > 0) {
    int status = 0;
    waitpid(pid_, &status, 0);
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    pid_ = -1;
    if (reader_.joinable()) reader_.join();
  }
  return exit_code_;
}

long ServerProcess::resident_kib() const {
  std::ifstream status("/proc/" + std::to_string(pid_) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

std::string ServerProcess::log() const {
  std::lock_guard<std::mutex> lock(log_mutex_);
  return log_;
}

std::string machine_summary() {
  std::ifstream in("/proc/cpuinfo");
  std::string line, model;
  int cores = 0;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0 && model.empty()) model = line.substr(line.find(':') + 2);
    if (line.rfind("processor", 0) == 0) ++cores;
  }
  utsname u{};
  uname(&u);
  return model + ", " + std::to_string(cores) + " cores, " + u.sysname + " " + u.release;
}

}  // namespace umbra::testing
