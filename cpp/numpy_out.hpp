// Eigen results handed to Python as NumPy arrays that own them. nanobind hands an Eigen matrix of under 1 KB back as a
// copy made by a Python call of numpy.copy (dense.h: "don't bother moving"), about 0.5 us an array; a call per step
// that returns several arrays pays it each time. Moved into a capsule the array is viewed by NumPy, not copied.
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstdint>
#include <type_traits>
#include <utility>

namespace pinstab {

// A NumPy array owning `value` (an Eigen vector or matrix, moved), with its shape and strides.
template <typename T>
nanobind::object numpy_out(T&& value) {
  using Held = std::decay_t<T>;
  using Array = nanobind::ndarray<nanobind::numpy, typename Held::Scalar>;
  static typename Held::Scalar no_data{};  // an empty array's pointer (Eigen's is null): never read nor written
  auto* held = new Held(std::forward<T>(value));
  nanobind::capsule owner(held, [](void* p) noexcept { delete static_cast<Held*>(p); });
  auto* data = held->size() ? held->data() : &no_data;
  if constexpr (Held::IsVectorAtCompileTime) {
    const size_t shape[1] = {static_cast<size_t>(held->size())};
    const int64_t strides[1] = {static_cast<int64_t>(held->innerStride())};
    return nanobind::cast(Array(data, 1, shape, owner, strides), nanobind::rv_policy::reference);
  } else {
    const size_t shape[2] = {static_cast<size_t>(held->rows()), static_cast<size_t>(held->cols())};
    const int64_t strides[2] = {static_cast<int64_t>(held->rowStride()), static_cast<int64_t>(held->colStride())};
    return nanobind::cast(Array(data, 2, shape, owner, strides), nanobind::rv_policy::reference);
  }
}

}  // namespace pinstab
