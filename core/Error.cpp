#include "core/Error.hpp"

#include <fmt/format.h>

namespace grainwave {

std::string InputLocation::to_string() const {
  return line > 0 ? fmt::format("{}:{}", file, line) : file;
}

namespace {
std::string format_input_error(const InputLocation& where, const std::string& key,
                               const std::string& message, const std::string& hint) {
  std::string text = where.to_string() + ": ";
  if (!key.empty()) text += fmt::format("key '{}': ", key);
  text += message;
  if (!hint.empty()) text += fmt::format(" ({})", hint);
  return text;
}
}  // namespace

InputError::InputError(InputLocation where, std::string key, std::string message, std::string hint)
    : std::runtime_error(format_input_error(where, key, message, hint)),
      where_(std::move(where)),
      key_(std::move(key)),
      message_(std::move(message)),
      hint_(std::move(hint)) {}

NumericalFailure::NumericalFailure(std::string what_failed, std::string where, double time,
                                   long step)
    : std::runtime_error(fmt::format("numerical failure at step {}, t = {:.9g}: {} at {}", step,
                                     time, what_failed, where)),
      what_failed_(std::move(what_failed)),
      where_(std::move(where)),
      time_(time),
      step_(step) {}

}  // namespace grainwave
