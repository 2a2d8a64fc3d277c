#pragma once
// A pseudo-terminal that plays the module's "BLE serial" port: the simulated module owns the
// master side, a host opens the slave (through a symlink at a path of the user's choice) exactly
// like /dev/ttyACM0 or an rfcomm tty. The slave is put in raw mode (no echo, no line editing).
//
// Flow control facts used by SimModule (Linux pty, checked on this kernel): the slave side
// buffers about 16 KB written by the master; writes then fail with EAGAIN until the host reads.
// poll() on the master reports POLLHUP while no process has the slave open, so "a host is
// connected" = no POLLHUP.
#include <cstddef>
#include <cstdint>
#include <string>

namespace btsm::sim {

class PtyBridge {
 public:
  // Creates the pty and the symlink `link_path` -> slave (an existing symlink is replaced; an
  // existing regular file is not touched: std::runtime_error).
  explicit PtyBridge(const std::string& link_path);
  ~PtyBridge();
  PtyBridge(const PtyBridge&) = delete;
  PtyBridge& operator=(const PtyBridge&) = delete;

  const std::string& slave_name() const { return slave_name_; }
  const std::string& link_path() const { return link_path_; }
  // The pty the replaced symlink led to when that pty was still there (another simulated module,
  // most likely still running: hosts that had it open keep talking to it), else "".
  const std::string& replaced_live_target() const { return replaced_live_target_; }

  bool host_connected() const;
  // False only when the symlink leads to another pty (a newer module on the same path took it).
  bool link_still_ours() const;
  // Non-blocking; returns bytes read (0 = nothing now).
  size_t read(uint8_t* buf, size_t n);
  // Non-blocking; returns bytes accepted (0 = buffer full).
  size_t write(const uint8_t* data, size_t n);
  // Waits up to timeout_ms for the master to become writable and a host to be connected.
  bool wait_writable(int timeout_ms) const;

 private:
  int master_ = -1;
  std::string slave_name_;
  std::string link_path_;
  std::string replaced_live_target_;
};

}  // namespace btsm::sim
