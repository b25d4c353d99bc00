// The range model (lidar::BatchRangeModel) that cufund._core.lidar.batch_cast and cufund._core.envs.prism_depth_cast
// both take as keyword arguments, read and checked once for both.
#pragma once

#include <cstdint>
#include <limits>
#include <string>

#include "batch_cast.h"
#include "pybind_common.h"

namespace cufund::py_bind {

// A real scalar >= 0 (finite unless allow_inf), else ValueError naming it.
inline double nonnegative_arg(const py::handle& obj, const char* field, bool allow_inf = false) {
  const double x = allow_inf ? real_arg(obj, field) : finite_arg(obj, field);
  if (!(x >= 0.0)) throw py::value_error(std::string(field) + " must be >= 0, got " + std::string(py::repr(obj)));
  return x;
}

// The casters' range-model arguments, as Python passed them.
struct BatchRangeModelArgs {
  py::handle range_min, range_max, miss_value, noise_std, noise_per_m, dropout, seed, frame;
};

// 0 <= range_min <= range_max (range_max may be inf), miss_value any real, noise_std and noise_per_m finite and
// >= 0, dropout in [0, 1), seed and frame integers >= 0; else TypeError or ValueError naming the argument.
inline lidar::BatchRangeModel batch_range_model_arg(const BatchRangeModelArgs& a) {
  constexpr std::int64_t kMaxInt = std::numeric_limits<std::int64_t>::max();
  lidar::BatchRangeModel model;
  model.range_min = static_cast<float>(nonnegative_arg(a.range_min, "range_min"));
  model.range_max = static_cast<float>(nonnegative_arg(a.range_max, "range_max", true));
  if (!(model.range_max >= model.range_min)) throw py::value_error("range_max must be >= range_min");
  model.miss_value = static_cast<float>(real_arg(a.miss_value, "miss_value"));
  model.noise_std = nonnegative_arg(a.noise_std, "noise_std");
  model.noise_per_m = nonnegative_arg(a.noise_per_m, "noise_per_m");
  model.dropout = nonnegative_arg(a.dropout, "dropout");
  if (!(model.dropout < 1.0)) {
    throw py::value_error("dropout must be in [0, 1), got " + std::string(py::repr(a.dropout)));
  }
  model.seed = static_cast<std::uint64_t>(int_arg(a.seed, "seed", 0, kMaxInt));
  model.frame = static_cast<std::uint64_t>(int_arg(a.frame, "frame", 0, kMaxInt));
  return model;
}

}  // namespace cufund::py_bind
