// Faults injected between host and module by a proxy (dropped bytes, flipped bits, a link cut
// mid-transfer). Invariants: no accepted sample differs from what the module sent, every
// missing sample is inside a reported gap, and the module's model is always entirely the old
// or entirely the new one.
#include "fake_module.hpp"
#include "host/link/model_flash.hpp"
#include "host/link/serial_transport.hpp"
#include "link_test_support.hpp"

#include <gtest/gtest.h>

#include <sys/socket.h>

#include <cstring>
#include <iostream>
#include <set>

using namespace btsm;
using namespace btsm::link;
using btsm::test::FakeModule;
using btsm::test::FakeModuleOptions;

namespace {

// host pty <-> proxy <-> socketpair <-> fake module
struct FaultyRig {
  test::PtyPair pty;
  int sp[2] = {-1, -1};
  std::unique_ptr<FakeModule> module;
  std::unique_ptr<test::FaultProxy> proxy;
  std::unique_ptr<SerialTransport> transport;
  std::unique_ptr<Session> session;
  FaultyRig(test::FaultPlan plan, FakeModuleOptions o = {}) {
    if (::socketpair(AF_UNIX, SOCK_STREAM, 0, sp) != 0) throw std::runtime_error("socketpair");
    module = std::make_unique<FakeModule>(sp[1], o);
    proxy = std::make_unique<test::FaultProxy>(pty.release_master(), sp[0], plan);
    transport = std::make_unique<SerialTransport>(pty.path);
    SessionOptions so;
    so.reply_timeout = Millis(150);
    so.retries = 8;
    session = std::make_unique<Session>(*transport, so);
    module->start();
  }
  ~FaultyRig() {
    session.reset();
    transport.reset();
    module->stop();
    proxy.reset();
  }
};

bool same_sample(const wire::Sample& a, const wire::Sample& b) {
  uint8_t pa[wire::kMaxPayload], pb[wire::kMaxPayload];
  const uint8_t na = wire::encode_sample(a, pa), nb = wire::encode_sample(b, pb);
  return na == nb && std::memcmp(pa, pb, na) == 0;
}

}  // namespace

class SampleFaults : public ::testing::TestWithParam<uint32_t> {};

TEST_P(SampleFaults, NoCorruptSampleAcceptedAndEveryLossReported) {
  test::FaultPlan plan;
  plan.seed = GetParam();
  plan.drop_prob = 0.002;
  plan.flip_prob = 0.002;
  plan.host_to_module = false;
  FakeModuleOptions o;
  o.sample_period = Millis(1);
  FaultyRig rig(plan, o);
  std::vector<uint32_t> accepted;
  std::optional<uint32_t> first;
  for (int n = 0; n < 400;) {
    auto ev = rig.session->next_sample(Millis(1000));
    ASSERT_TRUE(ev) << "stream stalled";
    const auto& s = ev->sample;
    if (!first) first = s.sample_index;
    // Bit for bit what the module sent for that index: a flipped bit never slips through.
    ASSERT_TRUE(same_sample(s, FakeModule::sample_for(s.sample_index, 0, 5000))) << "index " << s.sample_index;
    accepted.push_back(s.sample_index);
    ++n;
  }
  // Accepted indices + reported gaps tile [first, last] exactly once.
  std::set<uint32_t> covered(accepted.begin(), accepted.end());
  EXPECT_EQ(covered.size(), accepted.size()) << "a sample was accepted twice";
  uint64_t gap_total = 0;
  for (const auto& g : rig.session->tracker().gaps()) {
    for (uint32_t i = g.first; i <= g.last; ++i) EXPECT_TRUE(covered.insert(i).second) << "gap overlaps sample " << i;
    gap_total += g.count();
  }
  const uint32_t last = accepted.back();
  EXPECT_EQ(covered.size(), static_cast<size_t>(last - *first + 1));
  EXPECT_EQ(*covered.begin(), *first);
  EXPECT_EQ(*covered.rbegin(), last);
  EXPECT_EQ(gap_total, rig.session->tracker().lost());
  // With these rates some frames must have been damaged; the test is meaningless otherwise.
  EXPECT_GT(rig.proxy->dropped() + rig.proxy->flipped(), 0u);
  EXPECT_GT(rig.session->tracker().lost(), 0u);
}

INSTANTIATE_TEST_SUITE_P(Seeds, SampleFaults, ::testing::Values(1u, 2u, 3u, 4u));

class FlashFaults : public ::testing::TestWithParam<uint32_t> {};

TEST_P(FlashFaults, ModelIsOldOrNewNeverHalf) {
  test::FaultPlan plan;
  plan.seed = GetParam();
  plan.drop_prob = 0.003;
  plan.flip_prob = 0.003;
  FakeModuleOptions o;
  o.sample_period = Millis(20);
  FaultyRig rig(plan, o);
  const auto old_blob = test::make_test_blob(1);
  const auto new_blob = test::make_test_blob(2);
  // Install the old model (retry the whole upload if the link defeats it).
  for (int i = 0; i < 5 && rig.module->active_model() != old_blob; ++i) {
    try {
      flash_model(*rig.session, old_blob, test::fake_module_key());
    } catch (const LinkError&) {
    }
  }
  ASSERT_EQ(rig.module->active_model(), old_blob);
  bool ok = false;
  std::string err;
  try {
    ok = flash_model(*rig.session, new_blob, test::fake_module_key()).verified;
  } catch (const LinkError& e) {
    err = e.what();
  }
  const auto active = rig.module->active_model();
  std::cout << "seed " << GetParam() << ": " << (ok ? "verified" : "failed: " + err) << " (bytes dropped "
            << rig.proxy->dropped() << ", flipped " << rig.proxy->flipped() << ")\n";
  EXPECT_TRUE(active == old_blob || active == new_blob) << "half-written model";
  if (ok) {
    EXPECT_EQ(active, new_blob);
  } else {
    EXPECT_FALSE(err.empty());  // a failure is an error the user sees, never a silently wrong model
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, FlashFaults, ::testing::Values(11u, 12u, 13u, 14u, 15u));

TEST(LinkCut, DisconnectMidTransferKeepsOldModelAndReportsDeviceGone) {
  for (long cut : {30L, 150L, 400L, 900L}) {
    test::FaultPlan plan;
    plan.disconnect_after_host_bytes = cut;
    FakeModuleOptions o;
    o.sample_period = Millis(50);
    FaultyRig rig(plan, o);
    try {
      flash_model(*rig.session, test::make_test_blob(2), test::fake_module_key());
      FAIL() << "the link was cut after " << cut << " bytes, the upload cannot have finished";
    } catch (const LinkError& e) {
      EXPECT_TRUE(e.kind() == LinkErrorKind::kDeviceGone || e.kind() == LinkErrorKind::kTimeout) << e.what();
    }
    EXPECT_TRUE(rig.proxy->disconnected());
    EXPECT_TRUE(rig.module->active_model().empty()) << "cut at " << cut;
    EXPECT_EQ(rig.module->model_seq(), 0u);
  }
}
