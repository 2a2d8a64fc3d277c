#pragma once
// Errors of the module link. Every failure a user can meet (no adapter, permission denied, device
// gone, timeout, protocol refusal) is a LinkError whose kind lets the CLI pick an exit code and
// whose message names the device and says what to do about it.
#include <stdexcept>
#include <string>

namespace btsm::link {

enum class LinkErrorKind {
  kNoDevice,          // path/adapter/address does not exist or nothing answers there
  kPermissionDenied,  // the OS refused access (dialout group, capabilities)
  kDeviceGone,        // the device disappeared or hung up while in use
  kTimeout,           // no (valid) reply within the deadline, retries exhausted
  kProtocol,          // the peer answered but not as the protocol says (bad PDU, NACK, ...)
  kIo,                // any other OS error
  kUnsupported,       // the peer lacks what we need (no known BLE serial profile, ...)
};

const char* to_string(LinkErrorKind kind);

class LinkError : public std::runtime_error {
 public:
  LinkError(LinkErrorKind kind, const std::string& what) : std::runtime_error(what), kind_(kind) {}
  LinkErrorKind kind() const { return kind_; }

 private:
  LinkErrorKind kind_;
};

// Builds a LinkError from errno of a failed system call: `what` says which call on which device;
// ENOENT/ENODEV/ENXIO -> kNoDevice, EACCES/EPERM -> kPermissionDenied (with `permission_hint`),
// EIO/ENODEV on an open device -> kDeviceGone.
LinkError errno_error(int err, const std::string& what, const std::string& permission_hint = {});

}  // namespace btsm::link
