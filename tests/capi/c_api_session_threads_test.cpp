// c_api_session_threads_test.cpp — C API sessions over repeated calls and on threads.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "capi/c_api_session_support.hpp"

namespace ivr::test {
namespace {

// --- repeated calls ------------------------------------------------------------------------------

// Every array an operation handed out keeps its values however many operations follow (the
// session reuses only the buffers nobody holds).
TEST_F(CApiSession, ResultsKeepTheirValuesAfterLaterOperations) {
  const std::vector<float> target = perturbed_target();
  ASSERT_EQ(ivr_session_set_target(session_, target.data(), target.size()), IVR_OK);
  struct Held {
    std::string what;
    ArrayPtr array;
    std::vector<double> values;
  };
  std::vector<Held> held;
  const auto keep = [&](const std::string& what, ivr_array* a) {
    ASSERT_NE(a, nullptr) << what << ": " << ivr_last_error();
    held.push_back({what, ArrayPtr(a), doubles(a)});
  };
  for (int round = 0; round < 2; ++round) {
    const std::string r = " (round " + std::to_string(round) + ")";
    ivr_array* a = nullptr;
    ASSERT_EQ(ivr_session_render(session_, &a), IVR_OK);
    keep("render" + r, a);
    ivr_array* const image = a;
    for (const ivr_mode mode : {IVR_MODE_ADJOINT, IVR_MODE_FORWARD}) {
      ivr_array* loss = nullptr;
      ivr_array* groups[2] = {};
      const char* wrt = mode == IVR_MODE_ADJOINT ? "density,tf" : "tf,background";
      ASSERT_EQ(ivr_session_gradient(session_, nullptr, wrt, mode, IVR_LOSS_MSE, 0, &loss, groups,
                                     2, nullptr, nullptr),
                IVR_OK)
          << ivr_last_error();
      keep(std::string(wrt) + " loss" + r, loss);
      keep(std::string(wrt) + " group 0" + r, groups[0]);
      keep(std::string(wrt) + " group 1" + r, groups[1]);
    }
    ASSERT_EQ(ivr_session_jacobian(session_, "background", &a), IVR_OK);
    keep("jacobian" + r, a);
    ASSERT_EQ(ivr_session_project(session_, nullptr, &a), IVR_OK);
    keep("project" + r, a);
    ASSERT_EQ(ivr_session_backproject(session_, held.back().array.get(), &a), IVR_OK);
    keep("backproject" + r, a);
    // This round's render against the first round's.
    ASSERT_EQ(ivr_session_loss(session_, image, held.front().array.get(), IVR_LOSS_L1, &a), IVR_OK);
    keep("loss" + r, a);
    ASSERT_EQ(ivr_session_volume(session_, &a), IVR_OK);
    keep("volume" + r, a);
    // Different densities and target for the next round, so that its results differ.
    const std::vector<float> v = test_volume(16, 18, 20, 61 + unsigned(round));
    ASSERT_EQ(ivr_session_set_volume(session_, v.data(), IVR_FLOAT32, kShape), IVR_OK);
    std::vector<float> t(target);
    for (float& x : t) x *= 0.8f;
    ASSERT_EQ(ivr_session_set_target(session_, t.data(), t.size()), IVR_OK);
  }
  // The second round computed other values (else the check below could not see an overwrite).
  const size_t per_round = held.size() / 2;
  for (size_t i = 0; i < per_round; ++i)
    EXPECT_NE(held[i].values, held[i + per_round].values) << held[i].what;
  for (const Held& h : held) EXPECT_EQ(doubles(h.array.get()), h.values) << h.what << " changed";
}

// The fixed-point density gradient is a function of the session's state and the target alone:
// the same inputs give the same bits whatever gradients came before.
TEST_F(CApiSession, DeterministicDensityGradientsDependOnTheInputsAlone) {
  const std::vector<float> near = perturbed_target();
  const std::vector<float> far(near.size(), 1.f);  // a residual many times larger
  const ArrayPtr near_array = make_array(ctx_, {2, 16, 20, 4}, near);
  const ArrayPtr far_array = make_array(ctx_, {2, 16, 20, 4}, far);
  const auto gradient = [&](ivr_session* s, const ivr_array* target) {
    ivr_array* loss = nullptr;
    ivr_array* grad = nullptr;
    EXPECT_EQ(ivr_session_gradient(s, target, "density", IVR_MODE_ADJOINT, IVR_LOSS_MSE, 1, &loss,
                                   &grad, 1, nullptr, nullptr),
              IVR_OK)
        << ivr_last_error();
    const ArrayPtr a(loss), b(grad);
    return grad ? doubles(grad) : std::vector<double>{};
  };
  const std::vector<double> first = gradient(session_, near_array.get());
  EXPECT_GT(max_abs(first), 0.0);
  EXPECT_EQ(gradient(session_, near_array.get()), first) << "a repeated call";
  const std::vector<double> other = gradient(session_, far_array.get());
  EXPECT_NE(other, first);
  const std::vector<double> again = gradient(session_, near_array.get());
  ASSERT_EQ(again.size(), first.size());
  size_t differ = 0;
  double worst = 0;
  for (size_t i = 0; i < first.size(); ++i)
    if (again[i] != first[i]) {
      ++differ;
      worst = std::max(worst, std::abs(again[i] - first[i]) / max_abs(first));
    }
  EXPECT_EQ(differ, 0u) << "the same inputs after a gradient against another target: " << differ
                        << " of " << first.size() << " voxels differ, by up to " << worst
                        << " of the largest entry";
  ivr_session* fresh = nullptr;
  ASSERT_EQ(ivr_session_create(ctx_, scene_, nullptr, &fresh), IVR_OK);
  EXPECT_EQ(gradient(fresh, far_array.get()), other) << "a fresh session";
  EXPECT_EQ(ivr_session_release(fresh), IVR_OK);
  // And what is summed is the float-atomics gradient, to float rounding.
  ivr_array* loss = nullptr;
  ivr_array* grad = nullptr;
  ASSERT_EQ(ivr_session_gradient(session_, near_array.get(), "density", IVR_MODE_ADJOINT,
                                 IVR_LOSS_MSE, 0, &loss, &grad, 1, nullptr, nullptr),
            IVR_OK);
  const ArrayPtr a(loss), b(grad);
  expect_close(doubles(grad), first, 1e-5, 1e-6, "float-atomics density gradient");
}

// --- threads -------------------------------------------------------------------------------------

// What one session's loop computes: renders, adjoint losses and density gradients summed in fixed
// point (the same bits on every run), and TF/background gradients summed with float atomics.
struct Work {
  std::vector<std::vector<float>> renders;
  std::vector<double> losses;
  std::vector<std::vector<double>> density, tf;
  ivr_status status = IVR_OK;
  std::string error;
};

// `rounds` times: set a volume of its own, render, and take two gradients.
Work run_work(ivr_session* s, const std::vector<std::vector<float>>& volumes, int rounds) {
  Work w;
  const auto ok = [&](ivr_status st) {
    if (st != IVR_OK && w.status == IVR_OK) w.status = st, w.error = ivr_last_error();
    return st == IVR_OK;
  };
  for (int k = 0; k < rounds; ++k) {
    const std::vector<float>& v = volumes[size_t(k) % volumes.size()];
    if (!ok(ivr_session_set_volume(s, v.data(), IVR_FLOAT32, kShape))) return w;
    ivr_array* image = nullptr;
    if (!ok(ivr_session_render(s, &image))) return w;
    std::vector<float> pixels(kPixels);
    ok(ivr_array_download(image, pixels.data(), IVR_FLOAT32, pixels.size()));
    ivr_array_release(image);
    w.renders.push_back(pixels);
    for (const char* wrt : {"density", "tf,background"}) {
      ivr_array* loss = nullptr;
      ivr_array* groups[2] = {};
      size_t count = 0;
      if (!ok(ivr_session_gradient(s, nullptr, wrt, IVR_MODE_ADJOINT, IVR_LOSS_MSE, 1, &loss,
                                   groups, 2, &count, nullptr)))
        return w;
      double value = 0;
      ok(ivr_array_download(loss, &value, IVR_FLOAT64, 1));
      ivr_array_release(loss);
      std::vector<double> all;
      for (size_t i = 0; i < count; ++i) {
        int64_t shape[8];
        int rank = 0;
        ok(ivr_array_info(groups[i], &rank, shape, nullptr));
        std::vector<double> g(count_of(std::vector<int64_t>(shape, shape + rank)));
        ok(ivr_array_download(groups[i], g.data(), IVR_FLOAT64, g.size()));
        all.insert(all.end(), g.begin(), g.end());
        ivr_array_release(groups[i]);
      }
      w.losses.push_back(value);
      (std::string(wrt) == "density" ? w.density : w.tf).push_back(all);
    }
  }
  return w;
}

void expect_same_work(const Work& got, const Work& want, const std::string& who) {
  EXPECT_EQ(got.status, IVR_OK) << who << ": " << got.error;
  ASSERT_EQ(got.renders.size(), want.renders.size()) << who;
  ASSERT_EQ(got.density.size(), want.density.size()) << who;
  ASSERT_EQ(got.tf.size(), want.tf.size()) << who;
  for (size_t k = 0; k < want.renders.size(); ++k) {
    EXPECT_TRUE(got.renders[k] == want.renders[k]) << who << ": render " << k;
    EXPECT_TRUE(got.density[k] == want.density[k])
        << who << ": deterministic density gradient " << k;
    expect_close(got.tf[k], want.tf[k], 1e-5, 1e-5, who + ": tf,background gradient");
  }
  expect_close(got.losses, want.losses, 1e-6, 0, who + ": losses");
}

// Two sessions of one context, each on its own thread at once, compute what they compute one
// after the other on one thread.
TEST_F(CApiSession, TwoSessionsOfOneContextOnTwoThreadsMatchOneThread) {
  const std::vector<std::vector<float>> volumes_a = {volume_, test_volume(16, 18, 20, 31)};
  const std::vector<std::vector<float>> volumes_b = {test_volume(16, 18, 20, 32),
                                                     test_volume(16, 18, 20, 33)};
  const std::vector<float> target = perturbed_target();
  ivr_transfer_function* tf = nullptr;
  ASSERT_EQ(ivr_tf_from_json(ctx_, kGaussianTf, &tf), IVR_OK);
  // Fresh sessions for each run, so that both runs start from the same state.
  const auto fresh_sessions = [&](ivr_session** a, ivr_session** b) {
    ASSERT_EQ(ivr_session_create(ctx_, scene_, nullptr, a), IVR_OK) << ivr_last_error();
    ASSERT_EQ(ivr_session_create(ctx_, scene_, nullptr, b), IVR_OK) << ivr_last_error();
    ASSERT_EQ(ivr_session_set_tf(*b, tf), IVR_OK);  // b differs from a in more than data
    ASSERT_EQ(ivr_session_set_target(*a, target.data(), target.size()), IVR_OK);
    ASSERT_EQ(ivr_session_set_target(*b, target.data(), target.size()), IVR_OK);
  };
  const int rounds = 4;
  ivr_session *a = nullptr, *b = nullptr;
  ASSERT_NO_FATAL_FAILURE(fresh_sessions(&a, &b));
  const Work want_a = run_work(a, volumes_a, rounds), want_b = run_work(b, volumes_b, rounds);
  ASSERT_EQ(want_a.status, IVR_OK) << want_a.error;
  ASSERT_EQ(want_b.status, IVR_OK) << want_b.error;
  EXPECT_EQ(ivr_session_release(a), IVR_OK);
  EXPECT_EQ(ivr_session_release(b), IVR_OK);
  // The two sessions compute different things (else the check below would not see a mix-up).
  EXPECT_FALSE(want_a.renders[0] == want_b.renders[0]);

  ASSERT_NO_FATAL_FAILURE(fresh_sessions(&a, &b));
  Work got_a, got_b;
  std::thread ta([&] { got_a = run_work(a, volumes_a, rounds); });
  std::thread tb([&] { got_b = run_work(b, volumes_b, rounds); });
  ta.join();
  tb.join();
  expect_same_work(got_a, want_a, "session a");
  expect_same_work(got_b, want_b, "session b");
  EXPECT_EQ(ivr_session_release(a), IVR_OK);
  EXPECT_EQ(ivr_session_release(b), IVR_OK);
  EXPECT_EQ(ivr_tf_release(tf), IVR_OK);
}

// One session used by two threads in turn computes what one thread computes.
TEST_F(CApiSession, OneSessionUsedByTwoThreadsInTurnMatchesOneThread) {
  const std::vector<std::vector<float>> volumes = {volume_, test_volume(16, 18, 20, 41),
                                                   test_volume(16, 18, 20, 42)};
  const std::vector<float> target = perturbed_target();
  ivr_session* s = nullptr;
  ASSERT_EQ(ivr_session_create(ctx_, scene_, nullptr, &s), IVR_OK);
  ASSERT_EQ(ivr_session_set_target(s, target.data(), target.size()), IVR_OK);
  const Work first = run_work(s, volumes, 3), second = run_work(s, volumes, 3);
  EXPECT_EQ(ivr_session_release(s), IVR_OK);
  ASSERT_EQ(first.status, IVR_OK) << first.error;

  ASSERT_EQ(ivr_session_create(ctx_, scene_, nullptr, &s), IVR_OK);
  ASSERT_EQ(ivr_session_set_target(s, target.data(), target.size()), IVR_OK);
  Work got_first, got_second;
  std::thread t1([&] { got_first = run_work(s, volumes, 3); });
  t1.join();
  std::thread t2([&] { got_second = run_work(s, volumes, 3); });
  t2.join();
  expect_same_work(got_first, first, "first thread");
  expect_same_work(got_second, second, "second thread");
  EXPECT_EQ(ivr_session_release(s), IVR_OK);
}

// One session used by two threads at once: calls are serialised, and each gets the result of
// the session's state (unchanged here) — the same as one thread gets.
TEST_F(CApiSession, OneSessionUsedByTwoThreadsAtOnceGivesEveryCallItsResult) {
  const std::vector<float> target = perturbed_target();
  ASSERT_EQ(ivr_session_set_target(session_, target.data(), target.size()), IVR_OK);
  const auto compute = [&](std::vector<float>* image, std::vector<double>* grad,
                           std::vector<double>* lines) {
    ivr_array* a = nullptr;
    if (ivr_session_render(session_, &a) != IVR_OK) return false;
    ArrayPtr r(a);
    image->resize(kPixels);
    if (ivr_array_download(a, image->data(), IVR_FLOAT32, kPixels) != IVR_OK) return false;
    ivr_array* loss = nullptr;
    if (ivr_session_gradient(session_, nullptr, "density", IVR_MODE_ADJOINT, IVR_LOSS_MSE, 1, &loss,
                             &a, 1, nullptr, nullptr) != IVR_OK)
      return false;
    ArrayPtr l(loss), g(a);
    grad->resize(kVoxels);
    if (ivr_array_download(a, grad->data(), IVR_FLOAT64, kVoxels) != IVR_OK) return false;
    if (ivr_session_project(session_, nullptr, &a) != IVR_OK) return false;
    ArrayPtr p(a);
    lines->resize(kPixels / 4);
    return ivr_array_download(a, lines->data(), IVR_FLOAT64, kPixels / 4) == IVR_OK;
  };
  std::vector<float> image;
  std::vector<double> grad, lines;
  ASSERT_TRUE(compute(&image, &grad, &lines)) << ivr_last_error();
  std::atomic<int> mismatches{0}, failures{0};
  std::vector<std::string> errors(2);
  std::vector<std::thread> threads;
  for (int t = 0; t < 2; ++t)
    threads.emplace_back([&, t] {
      for (int k = 0; k < 6; ++k) {
        std::vector<float> i;
        std::vector<double> g, p;
        if (!compute(&i, &g, &p)) {
          ++failures;
          errors[size_t(t)] = ivr_last_error();
          return;
        }
        if (i != image || g != grad || p != lines) ++mismatches;
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(failures.load(), 0) << errors[0] << " | " << errors[1];
  EXPECT_EQ(mismatches.load(), 0);
}

// Four threads at once on one context: two with sessions of their own (set, render, gradients),
// and two sharing the fixture's session while also calling the one-shot API on the shared scene.
// Each computes what it computes alone on one thread. (The ThreadSanitizer build runs this, with
// every test named *Thread*, under the label `tsan`: scripts/test.sh --tsan.)
TEST_F(CApiSession, FourThreadsAtOnceOnOneContextMatchOneThread) {
  const std::vector<std::vector<float>> volumes_a = {test_volume(16, 18, 20, 51), volume_};
  const std::vector<std::vector<float>> volumes_b = {test_volume(16, 18, 20, 52),
                                                     test_volume(16, 18, 20, 53)};
  const std::vector<float> target = perturbed_target();
  const auto fresh_session = [&](ivr_session** s) {
    ASSERT_EQ(ivr_session_create(ctx_, scene_, nullptr, s), IVR_OK) << ivr_last_error();
    ASSERT_EQ(ivr_session_set_target(*s, target.data(), target.size()), IVR_OK);
  };
  // What each thread's work gives alone: a shared-session step (render and project) and a
  // one-shot step (render and project of the scene, unchanged by anyone).
  struct Shared {
    std::vector<float> render, one_shot_render, one_shot_lines;
    std::vector<double> lines;
    bool ok = false;
  };
  const size_t rays = kPixels / 4;
  const auto shared_step = [&](Shared* out) {
    out->render = session_render(session_);
    ivr_array* p = nullptr;
    if (ivr_session_project(session_, nullptr, &p) != IVR_OK) return;
    const ArrayPtr lines(p);
    out->lines = doubles(p);
    out->one_shot_render = one_shot_render(ctx_, scene_);
    out->one_shot_lines.assign(rays, 0.f);
    out->ok = ivr_project(ctx_, scene_, IVR_PRECISION_F32, nullptr, 0, out->one_shot_lines.data(),
                          rays) == IVR_OK;
  };
  const int rounds = 3;
  ivr_session *a = nullptr, *b = nullptr;
  ASSERT_NO_FATAL_FAILURE(fresh_session(&a));
  ASSERT_NO_FATAL_FAILURE(fresh_session(&b));
  const Work want_a = run_work(a, volumes_a, rounds), want_b = run_work(b, volumes_b, rounds);
  ASSERT_EQ(want_a.status, IVR_OK) << want_a.error;
  ASSERT_EQ(want_b.status, IVR_OK) << want_b.error;
  Shared want_shared;
  shared_step(&want_shared);
  ASSERT_TRUE(want_shared.ok) << ivr_last_error();
  EXPECT_FALSE(want_a.renders[0] == want_shared.render);  // a mix-up would show
  EXPECT_EQ(ivr_session_release(a), IVR_OK);
  EXPECT_EQ(ivr_session_release(b), IVR_OK);

  ASSERT_NO_FATAL_FAILURE(fresh_session(&a));
  ASSERT_NO_FATAL_FAILURE(fresh_session(&b));
  Work got_a, got_b;
  std::vector<Shared> got_shared(2 * rounds);
  std::vector<std::thread> threads;
  threads.emplace_back([&] { got_a = run_work(a, volumes_a, rounds); });
  threads.emplace_back([&] { got_b = run_work(b, volumes_b, rounds); });
  for (int t = 0; t < 2; ++t)
    threads.emplace_back([&, t] {
      for (int k = 0; k < rounds; ++k) shared_step(&got_shared[size_t(t * rounds + k)]);
    });
  for (std::thread& t : threads) t.join();
  expect_same_work(got_a, want_a, "session a");
  expect_same_work(got_b, want_b, "session b");
  for (size_t k = 0; k < got_shared.size(); ++k) {
    const Shared& got = got_shared[k];
    ASSERT_TRUE(got.ok) << "shared step " << k;
    EXPECT_TRUE(got.render == want_shared.render) << "shared session render " << k;
    EXPECT_TRUE(got.lines == want_shared.lines) << "shared session projection " << k;
    EXPECT_TRUE(got.one_shot_render == want_shared.one_shot_render) << "one-shot render " << k;
    EXPECT_TRUE(got.one_shot_lines == want_shared.one_shot_lines) << "one-shot projection " << k;
  }
  EXPECT_EQ(ivr_session_release(a), IVR_OK);
  EXPECT_EQ(ivr_session_release(b), IVR_OK);
}

}  // namespace
}  // namespace ivr::test
