#include "host/sim/runner/pty_bridge.hpp"

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <stdexcept>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

namespace btsm::sim {

namespace {
// Where the symlink `path` leads ("" when it is no symlink or cannot be read).
std::string link_target(const std::string& path) {
  char target[256] = {};
  const ssize_t n = readlink(path.c_str(), target, sizeof target - 1);
  return n > 0 ? std::string(target, size_t(n)) : std::string();
}
}  // namespace

PtyBridge::PtyBridge(const std::string& link_path) : link_path_(link_path) {
  struct stat st {};
  if (lstat(link_path.c_str(), &st) == 0 && !S_ISLNK(st.st_mode))
    throw std::runtime_error("pty: " + link_path + " exists and is not a symlink; not replacing it");
  struct stat live {};
  if (stat(link_path.c_str(), &live) == 0 && S_ISCHR(live.st_mode)) replaced_live_target_ = link_target(link_path);
  int slave = -1;
  char name[256] = {};
  if (openpty(&master_, &slave, name, nullptr, nullptr) != 0)
    throw std::runtime_error(std::string("pty: openpty failed: ") + std::strerror(errno));
  slave_name_ = name;
  termios tio{};
  tcgetattr(slave, &tio);
  cfmakeraw(&tio);
  cfsetispeed(&tio, B115200);
  cfsetospeed(&tio, B115200);
  tcsetattr(slave, TCSANOW, &tio);
  // The slave is closed again: the termios settings stay with the pty while the master is open,
  // and with no slave open poll() reports POLLHUP, which is how a connected host is detected.
  close(slave);
  fcntl(master_, F_SETFL, fcntl(master_, F_GETFL) | O_NONBLOCK);
  fcntl(master_, F_SETFD, FD_CLOEXEC);
  unlink(link_path.c_str());
  if (symlink(slave_name_.c_str(), link_path.c_str()) != 0) {
    const int e = errno;
    close(master_);
    throw std::runtime_error("pty: cannot create symlink " + link_path + ": " + std::strerror(e));
  }
}

PtyBridge::~PtyBridge() {
  if (link_target(link_path_) == slave_name_) unlink(link_path_.c_str());
  if (master_ >= 0) close(master_);
}

bool PtyBridge::link_still_ours() const {
  // Only a link that leads elsewhere counts: a link deleted (or being replaced: unlink, then
  // symlink) says nothing of another module.
  const std::string target = link_target(link_path_);
  return target.empty() || target == slave_name_;
}

bool PtyBridge::host_connected() const {
  pollfd p{master_, POLLOUT, 0};
  poll(&p, 1, 0);
  return !(p.revents & POLLHUP);
}

size_t PtyBridge::read(uint8_t* buf, size_t n) {
  const ssize_t r = ::read(master_, buf, n);
  return r > 0 ? size_t(r) : 0;  // EAGAIN, or EIO while no slave is open
}

size_t PtyBridge::write(const uint8_t* data, size_t n) {
  const ssize_t r = ::write(master_, data, n);
  return r > 0 ? size_t(r) : 0;
}

bool PtyBridge::wait_writable(int timeout_ms) const {
  pollfd p{master_, POLLOUT, 0};
  if (poll(&p, 1, timeout_ms) <= 0) return false;
  return (p.revents & POLLOUT) && !(p.revents & POLLHUP);
}

}  // namespace btsm::sim
