// api_test_support.hpp — what the tests of the header-only C++ layer (ivr/ivr.hpp) share.
#pragma once
#include <gtest/gtest.h>

#include <string>

#include "ivr/ivr.hpp"

namespace ivr::test {

// `f` throws ivr::api::Exception with `status` and a message holding `words` (naming the call).
template <typename F>
void expect_throw(F&& f, ivr_status status, const std::string& words) {
  try {
    f();
    ADD_FAILURE() << "no exception; wanted " << ivr_status_string(status);
  } catch (const api::Exception& e) {
    EXPECT_EQ(e.status(), status) << e.what();
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos)
        << "wanted '" << words << "' in: " << e.what();
  }
}

}  // namespace ivr::test
