// domain_support.hpp — the domain-parallel tests' workers (domain_test, domain_tomo_test): threads,
// each with its own device context, meeting in an in-process all-gather.
#pragma once
#include <gtest/gtest.h>

#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "test_support.hpp"

namespace ivr::test {

// Every worker's bytes to every worker, in rank order (what MPI_Allgatherv does for mpirun).
class Rendezvous {
 public:
  explicit Rendezvous(int ranks) : ranks_(ranks), parts_(ranks) {}
  std::vector<std::vector<unsigned char>> all_gather(int rank,
                                                     const std::vector<unsigned char>& mine) {
    std::unique_lock<std::mutex> lock(mutex_);
    const long round = round_;
    parts_[rank] = mine;
    if (++arrived_ == ranks_) {
      result_ = parts_;
      arrived_ = 0;
      ++round_;
      ready_.notify_all();
    } else {
      ready_.wait(lock, [&] { return round_ != round; });
    }
    ++calls_;
    return result_;
  }
  long calls() const { return calls_; }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  int ranks_, arrived_ = 0;
  long round_ = 0, calls_ = 0;
  std::vector<std::vector<unsigned char>> parts_, result_;
};

// Runs f(w, part, device) on `ranks` threads; what each returns, by worker.
// Each worker has a context of its own on the test device.
template <typename T, typename F>
inline std::vector<T> on_workers(int ranks, F f) {
  std::vector<std::unique_ptr<Device>> devices;
  for (int w = 0; w < ranks; ++w)
    devices.push_back(std::make_unique<Device>(std::to_string(device().info().index)));
  Rendezvous meeting(ranks);
  std::vector<T> out(ranks);
  std::vector<std::string> errors(ranks);
  std::vector<std::thread> threads;
  for (int w = 0; w < ranks; ++w)
    threads.emplace_back([&, w] {
      DomainPart part;
      part.rank = w, part.ranks = ranks;
      part.all_gather = [&, w](const std::vector<unsigned char>& mine) {
        return meeting.all_gather(w, mine);
      };
      try {
        out[w] = f(w, part, *devices[w]);
      } catch (const std::exception& e) {
        errors[w] = e.what();
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
