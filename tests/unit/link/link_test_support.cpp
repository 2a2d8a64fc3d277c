#include "link_test_support.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>

namespace btsm::test {

PtyPair::PtyPair() {
  char name[256];
  if (::openpty(&master, &slave, name, nullptr, nullptr) != 0) throw std::runtime_error("openpty failed");
  termios t{};
  ::tcgetattr(slave, &t);
  ::cfmakeraw(&t);
  ::tcsetattr(slave, TCSANOW, &t);
  path = name;
  ::fcntl(master, F_SETFL, ::fcntl(master, F_GETFL) | O_NONBLOCK);
  // A `btsm` run as a child process must not inherit either end: a master held open there
  // would keep the link "up" after the fake module closed it.
  ::fcntl(master, F_SETFD, FD_CLOEXEC);
  ::fcntl(slave, F_SETFD, FD_CLOEXEC);
}

PtyPair::~PtyPair() {
  close_master();
  if (slave >= 0) ::close(slave);
}

int PtyPair::release_master() {
  const int fd = master;
  master = -1;
  return fd;
}

void PtyPair::close_master() {
  if (master >= 0) ::close(master);
  master = -1;
}

TempDir::TempDir() {
  std::string tmpl = (std::filesystem::temp_directory_path() / "btsm-link-XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
}

FaultProxy::FaultProxy(int host_fd, int module_fd, FaultPlan plan)
    : host_fd_(host_fd), module_fd_(module_fd), plan_(plan), rng_(plan.seed) {
  thread_ = std::thread([this] { run(); });
}

FaultProxy::~FaultProxy() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
  if (host_fd_ >= 0) ::close(host_fd_);
  if (module_fd_ >= 0) ::close(module_fd_);
}

void FaultProxy::run() {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::uniform_int_distribution<int> bit(0, 7);
  uint8_t buf[512];
  while (running_) {
    pollfd p[2] = {{host_fd_, POLLIN, 0}, {module_fd_, POLLIN, 0}};
    const int nfds = host_fd_ >= 0 ? 2 : 1;
    pollfd* set = host_fd_ >= 0 ? p : p + 1;
    if (::poll(set, static_cast<nfds_t>(nfds), 10) <= 0) continue;
    for (int k = 0; k < 2; ++k) {
      const bool from_host = k == 0;
      if (from_host && host_fd_ < 0) continue;
      if (!(p[k].revents & POLLIN)) continue;
      const int src = from_host ? host_fd_ : module_fd_;
      const int dst = from_host ? module_fd_ : host_fd_;
      const ssize_t n = ::read(src, buf, sizeof buf);
      if (n <= 0) continue;
      const bool damage = from_host ? plan_.host_to_module : plan_.module_to_host;
      for (ssize_t i = 0; i < n; ++i) {
        if (from_host && plan_.disconnect_after_host_bytes >= 0 && host_bytes_ >= plan_.disconnect_after_host_bytes) {
          // Pull the plug: the host sees its tty hang up mid-transfer.
          disconnected_ = true;  // before close: the host may look as soon as it sees the hang-up
          ::close(host_fd_);
          host_fd_ = -1;
          break;
        }
        if (from_host) ++host_bytes_;
        uint8_t b = buf[i];
        if (damage && u(rng_) < plan_.drop_prob) {
          ++dropped_;
          continue;
        }
        if (damage && u(rng_) < plan_.flip_prob) {
          b = static_cast<uint8_t>(b ^ (1u << bit(rng_)));
          ++flipped_;
        }
        if (dst < 0) continue;
        for (;;) {
          const ssize_t w = ::write(dst, &b, 1);
          if (w == 1 || (w < 0 && errno != EAGAIN && errno != EINTR)) break;
          pollfd o{dst, POLLOUT, 0};
          ::poll(&o, 1, 10);
        }
      }
    }
  }
}

}  // namespace btsm::test
