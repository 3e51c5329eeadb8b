#pragma once
// The gl backend's sort of (key, value) pairs, used twice a frame by the broadphase: stage 6
// (Morton codes with object indices) and stage 8's pair sort (pairs as 64-bit keys). Up to
// VISCD_LOCAL_SORT keys one work group sorts them (sort_local.comp); more go through an LSD
// radix sort with 8-bit digits (radix_hist, radix_scan, radix_scatter). A part of its own
// because both callers share its programs and histogram buffer.

#include <cstdint>

#include "gl/frame_data.hpp"
#include "gl/objects.hpp"
#include "gl/program.hpp"
#include "viscd/result.hpp"

namespace viscd::gl {

class RadixSort {
 public:
  /// Reads FrameData::info (the key count on the GPU) and dispatch (the tile count).
  explicit RadixSort(FrameData& frame) : frame_(frame) {}

  /// Builds the programs. The context must be current.
  [[nodiscard]] Status init();
  /// Sorts the uvec2 keys in keys[0] (and the uint values in values[0], when not null) by their
  /// low key_bits, equal keys in the values' order (the values start ascending); returns which of
  /// the two buffers of each array holds the result.
  /// n_from_info: the key count is FrameInfo.active_count on the GPU, the passes are dispatched
  /// indirectly from it and n only bounds it (buffer sizes); otherwise the count is n and the
  /// host sizes the passes.
  int sort(Buffer* keys, Buffer* values, std::uint32_t n, int key_bits, bool n_from_info);
  /// Bytes of the histogram buffer (Detector::memory_bytes()).
  [[nodiscard]] std::uint64_t buffer_bytes() const { return static_cast<std::uint64_t>(hist_.size()); }

 private:
  FrameData& frame_;
  Program sort_local_, radix_hist_, radix_scan_, radix_scatter_;
  Buffer hist_;  // 256 digit counts per tile, turned into output offsets in place (radix_scan.comp)
};

}  // namespace viscd::gl
