#include "client_socket.hpp"

#include <poll.h>
#include <sys/socket.h>

namespace umbra {

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
