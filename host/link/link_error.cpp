#include "host/link/link_error.hpp"

#include <cerrno>
#include <cstring>

namespace btsm::link {

const char* to_string(LinkErrorKind kind) {
  switch (kind) {
    case LinkErrorKind::kNoDevice: return "no device";
    case LinkErrorKind::kPermissionDenied: return "permission denied";
    case LinkErrorKind::kDeviceGone: return "device gone";
    case LinkErrorKind::kTimeout: return "timeout";
    case LinkErrorKind::kProtocol: return "protocol error";
    case LinkErrorKind::kIo: return "I/O error";
    case LinkErrorKind::kUnsupported: return "unsupported device";
  }
  return "link error";
}

LinkError errno_error(int err, const std::string& what, const std::string& permission_hint) {
  std::string msg = what + ": " + std::strerror(err);
  switch (err) {
    case ENOENT:
    case ENXIO:
    case ENODEV:
    case EHOSTDOWN:
    case EHOSTUNREACH:
    case ECONNREFUSED:
      return LinkError(LinkErrorKind::kNoDevice, msg);
    case EACCES:
    case EPERM:
      if (!permission_hint.empty()) msg += " (" + permission_hint + ")";
      return LinkError(LinkErrorKind::kPermissionDenied, msg);
    case EIO:
    case ENOTCONN:
    case ECONNRESET:
    case EPIPE:
    case ESHUTDOWN:
      return LinkError(LinkErrorKind::kDeviceGone, msg);
    case ETIMEDOUT:
      return LinkError(LinkErrorKind::kTimeout, msg);
    default:
      return LinkError(LinkErrorKind::kIo, msg);
  }
}

}  // namespace btsm::link
