#pragma once
// The rig of the session and model-flash tests: a FakeModule on the master side of a pty, the
// host's serial transport on the slave path, and a session over it with short timeouts.
#include "fake_module.hpp"
#include "host/link/serial_transport.hpp"
#include "host/link/session.hpp"
#include "link_test_support.hpp"

namespace btsm::test {

// 300 ms per reply: the fake module answers at once, so a timeout means a lost frame.
inline link::SessionOptions quick_session(int retries) {
  link::SessionOptions so;
  so.reply_timeout = link::Millis(300);
  so.retries = retries;
  return so;
}

struct ModuleOnPty {
  PtyPair pty;
  FakeModule module;
  link::SerialTransport transport;
  link::Session session;
  explicit ModuleOnPty(FakeModuleOptions o = {}, link::SessionOptions so = quick_session(2))
      : module(pty.release_master(), o), transport(pty.path), session(transport, so) {
    module.start();
  }
};

}  // namespace btsm::test
