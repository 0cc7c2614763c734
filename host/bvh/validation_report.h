// The problems a BVH validation found: the first few in words, the rest counted
// (bvh_validator.cpp, compressed_bvh_validator.cpp).
#pragma once

#include "bvh/bvh_validator.h"

#include <cstddef>
#include <sstream>
#include <string>

namespace px::bvh_validation {

constexpr std::size_t kMaxReported = 10;

// Collects the first few problems and counts the rest.
class Report {
 public:
  template <typename... Parts>
  void error(const Parts&... parts) {
    ++count_;
    if (result_.errors.size() >= kMaxReported) return;
    std::ostringstream message;
    (message << ... << parts);
    result_.errors.push_back(message.str());
  }
  // Appends another report's problems after this one's (the cap applies to the sum).
  void merge(const Report& other) {
    for (const std::string& e : other.result_.errors)
      if (result_.errors.size() < kMaxReported) result_.errors.push_back(e);
    count_ += other.count_;
  }
  BvhValidation finish() {
    result_.ok = count_ == 0;
    if (count_ > result_.errors.size())
      result_.errors.push_back("... and " + std::to_string(count_ - result_.errors.size()) + " more");
    return result_;
  }

 private:
  BvhValidation result_;
  std::size_t count_ = 0;
};

}  // namespace px::bvh_validation
