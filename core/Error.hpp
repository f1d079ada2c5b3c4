#pragma once
// Errors that end a grainwave run, each with the exit code a user's script can rely on:
//   2  bad input (scene file, command line, unreadable or unwritable path): nothing is written
//   3  numerical failure (NaN/Inf, negative density, overlap...): the last good state is written
//   1  anything else (a bug or an unexpected system error)
#include <stdexcept>
#include <string>

namespace grainwave {

inline constexpr int kExitInputError = 2;
inline constexpr int kExitNumericalFailure = 3;

/// Where a piece of input came from: "cases/sod.toml:12" or "--set run.t_end=1".
struct InputLocation {
  std::string file;  ///< file name, or "command line"
  int line = 0;      ///< 1-based; 0 when the location has no line (a missing key's file)
  std::string to_string() const;
};

/// Bad input: names the file, line and key, and optionally a suggestion.
class InputError : public std::runtime_error {
 public:
  InputError(InputLocation where, std::string key, std::string message, std::string hint = {});
  const InputLocation& where() const { return where_; }
  const std::string& key() const { return key_; }
  const std::string& message() const { return message_; }
  const std::string& hint() const { return hint_; }

 private:
  InputLocation where_;
  std::string key_;
  std::string message_;
  std::string hint_;
};

/// A numerical failure detected by a state check: what failed, where and when.
class NumericalFailure : public std::runtime_error {
 public:
  NumericalFailure(std::string what_failed, std::string where, double time, long step);
  const std::string& what_failed() const { return what_failed_; }
  const std::string& where() const { return where_; }
  double time() const { return time_; }
  long step() const { return step_; }

 private:
  std::string what_failed_;
  std::string where_;
  double time_;
  long step_;
};

}  // namespace grainwave
