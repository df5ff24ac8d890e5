// The udev rules of the Debian package (packaging/70-volume-haptics.rules) give every
// device this program drives to the logged-in user: each SpaceMouse model of knownModels() on
// the hidraw subsystem and the Falcon's USB ID on the usb subsystem, all with TAG+="uaccess".

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "vh/devices/falcon_protocol.h"
#include "vh/devices/spacemouse_protocol.h"

namespace vh::devices::test {
namespace {

std::string readRules() {
  std::ifstream in(std::string(VH_SOURCE_DIR) + "/packaging/70-volume-haptics.rules");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The rule line (comments skipped) that matches `subsystem` and the ID, or empty.
std::string ruleFor(const std::string& rules, const std::string& subsystem, std::uint16_t vendor,
                    std::uint16_t product) {
  char ids[96];
  std::snprintf(ids, sizeof ids, "{idVendor}==\"%04x\", ATTR%s{idProduct}==\"%04x\"", vendor,
                subsystem == "hidraw" ? "S" : "", product);
  std::istringstream lines(rules);
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#') continue;
    if (line.find("SUBSYSTEM==\"" + subsystem + "\"") != std::string::npos && line.find(ids) != std::string::npos) {
      return line;
    }
  }
  return {};
}

TEST(UdevRules, EverySpaceMouseModelIsGivenToTheSeatUserOnHidraw) {
  const std::string rules = readRules();
  ASSERT_FALSE(rules.empty()) << "packaging/70-volume-haptics.rules not found";
  for (const spacemouse::Model& m : spacemouse::knownModels()) {
    const std::string rule = ruleFor(rules, "hidraw", m.vendor_id, m.product_id);
    ASSERT_FALSE(rule.empty()) << "no hidraw rule for " << m.name;
    EXPECT_NE(rule.find("TAG+=\"uaccess\""), std::string::npos) << rule;
  }
}

TEST(UdevRules, TheFalconIsGivenToTheSeatUserOnUsb) {
  const std::string rule = ruleFor(readRules(), "usb", falcon::kVendorId, falcon::kProductId);
  ASSERT_FALSE(rule.empty()) << "no usb rule for the Falcon";
  EXPECT_NE(rule.find("TAG+=\"uaccess\""), std::string::npos) << rule;
}

TEST(UdevRules, NoRuleCarriesATrailingComment) {
  // udev has no trailing comments: "KEY==x  # note" is a syntax error that drops the rule.
  std::istringstream lines(readRules());
  for (std::string line; std::getline(lines, line);) {
    if (!line.empty() && line[0] != '#') {
      EXPECT_EQ(line.find('#'), std::string::npos) << line;
    }
  }
}

}  // namespace
}  // namespace vh::devices::test
