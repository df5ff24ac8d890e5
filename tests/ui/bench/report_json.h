#pragma once
// Reading the benches' JSON reports in their tests.
#include <cmath>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace vh::ui::test {

/// The number at `key` of `j`; a test failure naming the key (and NaN) when it is missing or not
/// a number.
inline double number(const nlohmann::json& j, const std::string& key) {
  if (!j.contains(key) || !j[key].is_number()) {
    ADD_FAILURE() << key << " is missing or not a number in " << j.dump();
    return std::nan("");
  }
  return j[key].get<double>();
}

}  // namespace vh::ui::test
