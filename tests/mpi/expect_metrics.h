#pragma once
// Bit-for-bit comparison of metric results, shared by the MPI metrics tests.
#include <gtest/gtest.h>

#include "kernels/core/hausdorff.h"

namespace gimforge::test {

inline void expect_same(const OneSidedDistance& a, const OneSidedDistance& b) {
  EXPECT_EQ(a.max, b.max);
  EXPECT_EQ(a.mean, b.mean);
  EXPECT_EQ(a.rms, b.rms);
  EXPECT_EQ(a.area_samples, b.area_samples);
  EXPECT_EQ(a.vertex_samples, b.vertex_samples);
}

inline void expect_same(const HausdorffResult& got, const HausdorffResult& want) {
  expect_same(got.ab, want.ab);
  expect_same(got.ba, want.ba);
  EXPECT_EQ(got.rms, want.rms);
  EXPECT_EQ(got.diag, want.diag);
  EXPECT_EQ(got.psnr, want.psnr);
}

}  // namespace gimforge::test
