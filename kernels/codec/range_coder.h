#pragma once
/// \file range_coder.h
/// An adaptive binary range coder (the LZMA coder's design: 32-bit range; probabilities of 15 bits, not LZMA's 11, so that the long runs of zero coefficients
/// at low rates cost 0.0014 bits each instead of 0.02; adapted by
/// 1/32 of the error after every bit, carry propagation through a cached byte). The entropy coder of the
/// wavelet coefficients (wavelet_coder.h), as Davis's coder follows its quantizer with adaptive arithmetic
/// coding. Decoding never reads outside the buffer: past its end it reads zero bytes and counts them, so a
/// caller can refuse a truncated payload (RangeDecoder::overrun).
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace gimforge::rc {

/// The probability that the next bit is 0, in units of 2^-15, adapted as bits are coded.
struct BitModel {
  std::uint16_t p{1u << 14};
};

inline constexpr std::uint32_t kTop = std::uint32_t{1} << 24;
inline constexpr int kModelBits = 15;
inline constexpr int kAdaptShift = 5;

class RangeEncoder {
 public:
  void encode(BitModel& m, unsigned bit) {
    const std::uint32_t bound = (range_ >> kModelBits) * m.p;
    if (bit == 0) {
      range_ = bound;
      m.p = static_cast<std::uint16_t>(m.p + (((1u << kModelBits) - m.p) >> kAdaptShift));
    } else {
      low_ += bound;
      range_ -= bound;
      m.p = static_cast<std::uint16_t>(m.p - (m.p >> kAdaptShift));
    }
    normalize();
  }
  /// A bit of probability 1/2, without a model (signs).
  void encode_direct(unsigned bit) {
    range_ >>= 1;
    if (bit != 0) low_ += range_;
    normalize();
  }
  /// Flushes the coder and returns the bytes. The encoder is spent afterwards.
  [[nodiscard]] std::vector<std::uint8_t> finish() {
    for (int i = 0; i < 5; ++i) shift_low();
    return std::move(out_);
  }
  [[nodiscard]] std::size_t bytes_so_far() const { return out_.size() + cache_size_; }

 private:
  void normalize() {
    while (range_ < kTop) {
      range_ <<= 8;
      shift_low();
    }
  }
  void shift_low() {
    if (static_cast<std::uint32_t>(low_) < 0xFF000000u || (low_ >> 32) != 0) {
      const auto carry = static_cast<std::uint8_t>(low_ >> 32);
      std::uint8_t temp = cache_;
      do {
        out_.push_back(static_cast<std::uint8_t>(temp + carry));
        temp = 0xFF;
      } while (--cache_size_ != 0);
      cache_ = static_cast<std::uint8_t>(low_ >> 24);
    }
    ++cache_size_;
    low_ = (low_ & 0x00FFFFFFu) << 8;
  }

  std::uint64_t low_{0};
  std::uint32_t range_{0xFFFFFFFFu};
  std::uint8_t cache_{0};
  std::uint64_t cache_size_{1};
  std::vector<std::uint8_t> out_;
};

class RangeDecoder {
 public:
  explicit RangeDecoder(std::span<const std::uint8_t> bytes) : in_(bytes) {
    for (int i = 0; i < 5; ++i) code_ = (code_ << 8) | next();
  }
  unsigned decode(BitModel& m) {
    const std::uint32_t bound = (range_ >> kModelBits) * m.p;
    unsigned bit = 0;
    if (code_ < bound) {
      range_ = bound;
      m.p = static_cast<std::uint16_t>(m.p + (((1u << kModelBits) - m.p) >> kAdaptShift));
    } else {
      code_ -= bound;
      range_ -= bound;
      m.p = static_cast<std::uint16_t>(m.p - (m.p >> kAdaptShift));
      bit = 1;
    }
    normalize();
    return bit;
  }
  unsigned decode_direct() {
    range_ >>= 1;
    unsigned bit = 0;
    if (code_ >= range_) {
      code_ -= range_;
      bit = 1;
    }
    normalize();
    return bit;
  }
  /// Bytes read past the end of the buffer. The encoder's flush writes 4 bytes the decoder does not need,
  /// so a complete payload never overruns by more than that.
  [[nodiscard]] std::size_t overrun() const { return overrun_; }

 private:
  std::uint32_t next() {
    if (pos_ < in_.size()) return in_[pos_++];
    ++overrun_;
    return 0;
  }
  void normalize() {
    while (range_ < kTop) {
      range_ <<= 8;
      code_ = (code_ << 8) | next();
    }
  }

  std::span<const std::uint8_t> in_;
  std::size_t pos_{0};
  std::size_t overrun_{0};
  std::uint32_t code_{0};
  std::uint32_t range_{0xFFFFFFFFu};
};

}  // namespace gimforge::rc
