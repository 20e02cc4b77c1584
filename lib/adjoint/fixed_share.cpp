// fixed_share.cpp — a data-parallel share's two collectives for the fixed-point adjoint
// (FixedShare::agree, FixedShare::add), built from the workers' sum of doubles.
#include <algorithm>

#include "adjoint/adjoint.hpp"
#include "ivr/error.hpp"

namespace ivr {

void set_share_collectives(FixedShare& f, int worker, int workers,
                           const std::function<void(std::vector<double>&)>& sum) {
  if (workers < 1 || worker < 0 || worker >= workers || !sum)
    throw Error(Status::invalid_argument, "data-parallel share: worker " + std::to_string(worker) +
                                              " of " + std::to_string(workers) +
                                              (sum ? "" : " without a sum"));
  // Maxima from the sum: each worker's values in its own slots, the others' 0 (exact).
  f.agree = [sum, workers, worker](std::int64_t& over_cap, float& largest, float& largest_ray) {
    std::vector<double> v(1 + 2 * std::size_t(workers), 0.0);
    v[0] = double(over_cap);  // (a count of rays: exact)
    v[1 + 2 * std::size_t(worker)] = largest;
    v[2 + 2 * std::size_t(worker)] = largest_ray;
    sum(v);
    over_cap = std::int64_t(v[0]);
    for (int w = 0; w < workers; ++w) {
      largest = std::max(largest, float(v[1 + 2 * std::size_t(w)]));
      largest_ray = std::max(largest_ray, float(v[2 + 2 * std::size_t(w)]));
    }
  };
  // Exact integer sums through a sum of doubles: each value as its low 32 bits (< 2^32) and the
  // rest (|·| < 2^31), whose sums over fewer than 2^21 workers stay below 2^53.
  f.add = [sum](std::vector<std::int64_t>& values) {
    std::vector<double> v(2 * values.size());
    for (std::size_t i = 0; i < values.size(); ++i) {
      v[2 * i] = double(std::uint64_t(values[i]) & 0xffffffffu);
      v[2 * i + 1] = double(values[i] >> 32);  // (arithmetic: values[i] = high·2^32 + low)
    }
    sum(v);
    for (std::size_t i = 0; i < values.size(); ++i) {
      const auto high = static_cast<__int128>(static_cast<std::int64_t>(v[2 * i + 1]));
      const auto low = static_cast<__int128>(static_cast<std::int64_t>(v[2 * i]));
      values[i] = static_cast<std::int64_t>(high * (__int128(1) << 32) + low);
    }
  };
}

}  // namespace ivr
