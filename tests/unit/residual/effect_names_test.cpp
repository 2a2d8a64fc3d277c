// Networks the residual loop builds itself (augment) hold every name once, so a model written
// from one (the demo's final_model.json) reads back through the network reader, which refuses
// two links, sources, nodes or parameters of one name (probe 7, P3-o).
#include "host/residual/effects.hpp"
#include "host/thermal/network.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace btsm::residual {
namespace {

namespace th = btsm::thermal;

std::vector<EffectSpec> every_effect(const th::Network& net) {
  const int rear = net.node_index("rear_bearing"), housing = net.node_index("housing"), front = net.node_index("front_bearing");
  std::vector<EffectSpec> out;
  for (const EffectKind k : all_effect_kinds()) {
    EffectSpec e;
    e.kind = k;
    e.nodes = {rear, front};
    if (k == EffectKind::SensorLag || k == EffectKind::SensorDrift) e.column = "T1";
    if (k == EffectKind::SecondBoundary) e.column = "coolant_c";
    if (k == EffectKind::EventConductance) e.column = "lid_open";
    if (k == EffectKind::CoupledHeat) e.hot = rear, e.cold = housing;
    out.push_back(e);
  }
  return out;
}

TEST(EffectNames, EveryAugmentedNetworkReadsBackThroughTheNetworkReader) {
  const th::Network base = th::preset_network("spindle4");
  const Eigen::VectorXd p = th::default_parameters(base);
  for (const EffectSpec& e : every_effect(base)) {
    const AugmentedModel m = augment(base, p, e, {});
    const std::string label = effect_label(e, base);
    EXPECT_NO_THROW(th::network_from_json(th::network_to_json(m.net), label)) << label;
  }
}

// A network that already has a link (or a source) of the name an effect gives its own is refused
// by augment, as a node or parameter of that name is: the result could not be read back.
TEST(EffectNames, AnEffectLinkOrSourceNamedLikeOneOfTheNetworkIsRefused) {
  th::Network base = th::preset_network("spindle4");
  const Eigen::VectorXd p = th::default_parameters(base);
  EffectSpec latent;
  latent.kind = EffectKind::LatentMass;
  latent.nodes = {base.node_index("housing")};
  base.links.front().name = "g_latent_housing";
  try {
    augment(base, p, latent, {});
    FAIL() << "a second link 'g_latent_housing' was made";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("effect link 'g_latent_housing' already exists"), std::string::npos) << e.what();
  }
  EffectSpec extra;
  extra.kind = EffectKind::ExtraHeatInput;
  extra.nodes = {base.node_index("housing")};
  base.sources.front().name = "extra_housing";
  try {
    augment(base, p, extra, {});
    FAIL() << "a second source 'extra_housing' was made";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("effect source 'extra_housing' already exists"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace btsm::residual
