// domain_support.hpp — the domain-parallel tests' workers (domain_test, domain_tomo_test): threads,
// each with its own device context, meeting in the library's in-process all-gather.
#pragma once
#include <gtest/gtest.h>

#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "multi_device/worker_sum.hpp"
#include "test_support.hpp"

namespace ivr::test {

// Runs f(w, part, device) on `ranks` threads; what each returns, by worker.
// Each worker has a context of its own on the test device.
template <typename T, typename F>
inline std::vector<T> on_workers(int ranks, F f) {
  const std::vector<std::unique_ptr<Device>> devices = device_contexts(ranks);
  WorkerGather meeting(ranks);  // (the library's, as its several devices' slabs meet)
  std::vector<T> out(ranks);
  std::vector<std::string> errors(ranks);
  std::vector<std::thread> threads;
  for (int w = 0; w < ranks; ++w)
    threads.emplace_back([&, w] {
      DomainPart part;
      part.rank = w, part.ranks = ranks;
      part.all_gather = meeting.of(w);
      try {
        out[w] = f(w, part, *devices[w]);
      } catch (const std::exception& e) {
        errors[w] = e.what();
        meeting.abort();  // (the others' exchanges stop rather than wait for this worker)
      }
    });
  for (std::thread& t : threads) t.join();
  for (int w = 0; w < ranks; ++w) EXPECT_EQ(errors[w], "") << "worker " << w;
  return out;
}

// Expects f() to throw an ivr::Error of `status` whose message names `part`.
template <typename F>
inline void expect_error(F f, Status status, const std::string& part) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one naming '" << part << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), status) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

}  // namespace ivr::test
