// A fast 64-bit hash of a block of memory, for cache keys and file checksums over hundreds of
// megabytes (the 10M-triangle heightfield's triangles are 1 GB): four independent lanes of
// 8-byte words, each round multiply-rotate-multiply (the round and the constants of xxHash64),
// merged and avalanched at the end. Byte-at-a-time FNV-1a runs at about 1 byte per cycle; this
// runs at memory speed. Not cryptographic: a key collides only by accident, one in 2^64.
// The value depends on the bytes alone (little-endian word loads on every platform we build
// for), never on the address.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace px {

class ContentHash {
 public:
  explicit ContentHash(std::uint64_t seed = 0) {
    lane_[0] = seed + kP1 + kP2;
    lane_[1] = seed + kP2;
    lane_[2] = seed;
    lane_[3] = seed - kP1;
  }

  // Adds `n` bytes; calls may split the input anywhere (the result is that of one call).
  void bytes(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    total_ += n;
    if (buffered_ > 0) {  // complete the pending block first
      const std::size_t take = n < kBlock - buffered_ ? n : kBlock - buffered_;
      std::memcpy(buffer_ + buffered_, p, take);
      buffered_ += take;
      p += take;
      n -= take;
      if (buffered_ < kBlock) return;
      block(buffer_);
      buffered_ = 0;
    }
    for (; n >= kBlock; p += kBlock, n -= kBlock) block(p);
    std::memcpy(buffer_, p, n);
    buffered_ = n;
  }
  template <typename T>
  void value(const T& v) {
    bytes(&v, sizeof v);
  }

  std::uint64_t digest() const {
    std::uint64_t h = rotl(lane_[0], 1) + rotl(lane_[1], 7) + rotl(lane_[2], 12) + rotl(lane_[3], 18);
    for (const std::uint64_t l : lane_) h = (h ^ round(0, l)) * kP1 + kP4;
    h += total_;
    // The tail: whole words, then the bytes left.
    std::size_t i = 0;
    for (; i + 8 <= buffered_; i += 8) h = rotl(h ^ round(0, load(buffer_ + i)), 27) * kP1 + kP4;
    for (; i < buffered_; ++i) h = rotl(h ^ (buffer_[i] * kP5), 11) * kP1;
    h ^= h >> 33;
    h *= kP2;
    h ^= h >> 29;
    h *= kP3;
    h ^= h >> 32;
    return h;
  }

 private:
  static constexpr std::uint64_t kP1 = 0x9E3779B185EBCA87ull, kP2 = 0xC2B2AE3D27D4EB4Full, kP3 = 0x165667B19E3779F9ull,
                                 kP4 = 0x85EBCA77C2B2AE63ull, kP5 = 0x27D4EB2F165667C5ull;
  static constexpr std::size_t kBlock = 32;

  static std::uint64_t rotl(std::uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }
  static std::uint64_t round(std::uint64_t acc, std::uint64_t w) { return rotl(acc + w * kP2, 31) * kP1; }
  static std::uint64_t load(const unsigned char* p) {
    std::uint64_t w;
    std::memcpy(&w, p, 8);
    return w;
  }
  void block(const unsigned char* p) {
    for (int k = 0; k < 4; ++k) lane_[k] = round(lane_[k], load(p + 8 * k));
  }

  std::uint64_t lane_[4];
  unsigned char buffer_[kBlock] = {};
  std::size_t buffered_ = 0;
  std::uint64_t total_ = 0;
};

// One call's worth.
inline std::uint64_t content_hash(const void* data, std::size_t n, std::uint64_t seed = 0) {
  ContentHash h(seed);
  h.bytes(data, n);
  return h.digest();
}

}  // namespace px
