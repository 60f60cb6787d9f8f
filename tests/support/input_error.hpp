// Checks that a call refuses bad input with an InputError at the right file, line and column.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "stepcal/common/error.hpp"

namespace stepcal::test {

/// What an InputError reported.
/// file is the file name only (no folder); line is -1 when nothing was thrown.
struct Refusal {
  std::string file;
  int line = -1;
  std::string column;
  std::string what;
};

/// The InputError that call() throws; adds a test failure (and returns line -1) when it returns.
template <typename Call>
Refusal refusalOf(Call&& call) {
  try {
    std::forward<Call>(call)();
  } catch (const InputError& e) {
    return {std::filesystem::path(e.file()).filename().string(), e.line(), e.column(), e.what()};
  }
  ADD_FAILURE() << "the input was accepted; expected an InputError";
  return {};
}

/// Expects call() to throw an InputError at file (name only), line and column, with every one of
/// message_parts in its message. Line 0 and column "" mean the error names none.
template <typename Call>
void expectInputError(Call&& call, const std::string& file, int line, const std::string& column,
                      const std::vector<std::string>& message_parts) {
  const Refusal r = refusalOf(std::forward<Call>(call));
  if (r.line < 0) return;  // accepted: already a failure
  EXPECT_EQ(r.file, file) << r.what;
  EXPECT_EQ(r.line, line) << r.what;
  EXPECT_EQ(r.column, column) << r.what;
  for (const std::string& part : message_parts) {
    EXPECT_NE(r.what.find(part), std::string::npos) << "'" << part << "' not in: " << r.what;
  }
}

/// Expects call() to throw an InputError that names no file, with every one of message_parts.
template <typename Call>
void expectInputError(Call&& call, const std::vector<std::string>& message_parts) {
  expectInputError(std::forward<Call>(call), "", 0, "", message_parts);
}

}  // namespace stepcal::test
