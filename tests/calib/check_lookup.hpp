#pragma once
/// @file
/// Test helpers: one check of a calib-check report by name, and one of its named values.
#include <catch2/catch.hpp>
#include <stdexcept>
#include <string>

#include "roe/calib/calib_check.hpp"

namespace roe::test {

inline const calib::CheckResult& check_named(const calib::CalibReport& r, const std::string& name) {
  for (const auto& c : r.checks)
    if (c.name == name) return c;
  FAIL("no check " << name);
  throw std::logic_error("unreachable");
}

inline double check_value(const calib::CheckResult& c, const std::string& key) {
  for (const auto& [k, v] : c.values)
    if (k == key) return v;
  FAIL("no value " << key << " in " << c.name);
  return 0.0;
}

}  // namespace roe::test
