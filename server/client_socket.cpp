#include "client_socket.hpp"

#include <cstdlib>

#include <dirent.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>

namespace umbra {

namespace {

// The numeric host and port of a socket address, as cpp-httplib writes them
// into Request::remote_addr / remote_port.
bool numeric_address(const sockaddr_storage& address, socklen_t length, std::string& host, int& port) {
  char host_buffer[NI_MAXHOST], port_buffer[NI_MAXSERV];
  if (getnameinfo(reinterpret_cast<const sockaddr*>(&address), length, host_buffer, sizeof host_buffer, port_buffer,
                  sizeof port_buffer, NI_NUMERICHOST | NI_NUMERICSERV) != 0)
    return false;
  host = host_buffer;
  port = std::atoi(port_buffer);
  return true;
}

bool connects(int fd, const std::string& remote_addr, int remote_port, int local_port) {
  sockaddr_storage address{};
  socklen_t length = sizeof address;
  std::string host;
  int port = -1;
  if (getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) return false;
  if (!numeric_address(address, length, host, port) || port != local_port) return false;
  length = sizeof address;
  if (getpeername(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) return false;
  return numeric_address(address, length, host, port) && port == remote_port && host == remote_addr;
}

}  // namespace

int find_client_socket(const std::string& remote_addr, int remote_port, int local_port) {
  thread_local int remembered = -1;
  if (remembered >= 0 && connects(remembered, remote_addr, remote_port, local_port)) return remembered;
  remembered = -1;
  DIR* fds = opendir("/proc/self/fd");
  if (!fds) return -1;
  while (dirent* entry = readdir(fds)) {
    char* end = nullptr;
    const long fd = std::strtol(entry->d_name, &end, 10);
    if (end == entry->d_name || *end != '\0' || fd == dirfd(fds)) continue;
    struct stat info {};
    if (fstat(int(fd), &info) != 0 || !S_ISSOCK(info.st_mode)) continue;
    if (connects(int(fd), remote_addr, remote_port, local_port)) {
      remembered = int(fd);
      break;
    }
  }
  closedir(fds);
  return remembered;
}

bool peer_closed(int socket) {
  if (socket < 0) return false;  // unknown: assume the client is there
  pollfd p{socket, POLLIN | POLLRDHUP, 0};
  if (poll(&p, 1, 0) <= 0) return false;  // nothing happened: still connected
  if (p.revents & (POLLHUP | POLLERR | POLLRDHUP)) return true;
  // Readable: a pipelined request (still there), or end of stream (gone).
  char byte;
  return recv(socket, &byte, 1, MSG_PEEK | MSG_DONTWAIT) == 0;
}

}  // namespace umbra
