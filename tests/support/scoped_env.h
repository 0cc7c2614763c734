// Sets (or unsets) an environment variable for one scope and puts back what was there. The
// environment module (io/environment.h) reads the variables once, so it is read again on both
// ends: code under test sees the value while the scope lasts, and the old one after.
#pragma once

#include "io/environment.h"

#include <cstdlib>
#include <optional>
#include <string>

namespace px::test {

class ScopedEnv {
 public:
  // value nullopt: the variable is unset for the scope.
  ScopedEnv(const char* name, const std::optional<std::string>& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    set(value);
  }
  ~ScopedEnv() { set(old_); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  void set(const std::optional<std::string>& value) {
    if (value)
      setenv(name_.c_str(), value->c_str(), 1);
    else
      unsetenv(name_.c_str());
    reload_environment_for_tests();
  }

  std::string name_;
  std::optional<std::string> old_;
};

}  // namespace px::test
