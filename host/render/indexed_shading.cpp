#include "render/indexed_shading.h"

#include "render/scene_tables.h"

#include <cstring>
#include <stdexcept>

#include <sys/mman.h>
#include <unistd.h>

namespace px {
namespace {

constexpr std::size_t kRecordWords = sizeof(IndexedTriangleShading) / 4;  // 4
constexpr std::size_t kVertexWords = sizeof(ShadingVertex) / 4;           // 5
// The recent-vertex table: 2^17 slots (1 MiB, in a core's L2), well past the vertices between
// a grid vertex's first and last triangle (two rows of quads: a few thousand at 10M triangles).
constexpr std::uint32_t kRecentBits = 17;

std::uint32_t bits_of(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

}  // namespace

IndexedShadingBuilder::IndexedShadingBuilder(std::size_t triangles)
    : triangles_(triangles),
      block_(std::make_shared<std::vector<std::uint32_t, UninitializedAllocator<std::uint32_t>>>()),
      recent_(std::size_t{1} << kRecentBits, 0u),
      all_(std::size_t{1} << 16, 0u) {
  // Sized for a vertex shared by two triangles or more (at most half full; a grid's are shared
  // by six): growing it would place every entry again at random.
  while (all_.size() < triangles) all_.resize(2 * all_.size());
  // The relative offsets are 32-bit float counts: the whole block must be addressable by them.
  const std::size_t words = kRecordWords * triangles + kVertexWords * 3 * triangles;
  if (words >= 0xffffffffull) throw std::length_error("too many triangles for indexed shading records");
  block_->resize(words);  // uninitialised: pages are touched as they are written
}

namespace {
std::uint64_t hash_of(const std::uint32_t* w) {
  std::uint64_t h = 0x9e3779b97f4a7c15ull;
  for (int i = 0; i < 5; ++i) h = (h ^ w[i]) * 0xff51afd7ed558ccdull;
  return h ^ (h >> 29);
}
}  // namespace

std::uint32_t IndexedShadingBuilder::entry(const std::uint32_t* w, std::uint64_t h) {
  std::uint32_t* table = block_->data() + kRecordWords * triangles_;
  // A slot holds the entry's index + 1 and, above it, 32 bits of its hash: a slot of another
  // vertex is passed over without reading its entry (a cache miss of its own).
  const std::uint64_t tag = h & 0xffffffff00000000ull;
  const auto same = [&](std::uint64_t slot) {
    return (slot & 0xffffffff00000000ull) == tag &&
           std::memcmp(table + kVertexWords * (static_cast<std::uint32_t>(slot) - 1), w, 20) == 0;
  };
  // The vertices made lately first (in a core's cache), then every vertex.
  std::uint64_t& recent = recent_[static_cast<std::size_t>((h >> 8) & ((std::size_t{1} << kRecentBits) - 1))];
  if (recent != 0 && same(recent)) return static_cast<std::uint32_t>(recent) - 1;
  std::size_t mask = all_.size() - 1, at = static_cast<std::size_t>(h) & mask;
  for (; all_[at] != 0; at = (at + 1) & mask)
    if (same(all_[at])) {
      recent = all_[at];
      return static_cast<std::uint32_t>(all_[at]) - 1;
    }
  const auto e = static_cast<std::uint32_t>(vertices_++);
  std::memcpy(table + kVertexWords * e, w, 20);
  all_[at] = recent = tag | (e + 1);
  if (2 * vertices_ > all_.size()) {  // at most half full: twice the slots, every entry again
    std::vector<std::uint64_t> wider(2 * all_.size(), 0u);
    mask = wider.size() - 1;
    for (const std::uint64_t slot : all_) {
      if (slot == 0) continue;
      const std::uint64_t hv = hash_of(table + kVertexWords * (static_cast<std::uint32_t>(slot) - 1));
      std::size_t k = static_cast<std::size_t>(hv) & mask;
      while (wider[k] != 0) k = (k + 1) & mask;
      wider[k] = slot;
    }
    all_.swap(wider);
  }
  return e;
}

void IndexedShadingBuilder::add(const SceneTriangle& t) {
  if (added_ >= triangles_) throw std::logic_error("IndexedShadingBuilder: more triangles than announced");
  // A triangle's lookups are made kPending triangles later, their slots in the table of every
  // vertex fetched meanwhile: on a large mesh those lookups miss the cache, and this way several
  // are in flight at once. The records and the entries come out the same.
  Pending& p = pending_[added_ % kPending];
  if (added_ >= kPending) resolve(p);
  p.triangle = added_++;
  p.material = t.material;
  for (int k = 0; k < 3; ++k) {
    const std::uint32_t w[5] = {bits_of(t.n[k].x), bits_of(t.n[k].y), bits_of(t.n[k].z), bits_of(t.uv[k].x),
                                bits_of(t.uv[k].y)};
    std::memcpy(p.w[k], w, sizeof w);
    p.h[k] = hash_of(w);
    __builtin_prefetch(&all_[static_cast<std::size_t>(p.h[k]) & (all_.size() - 1)]);
  }
}

void IndexedShadingBuilder::resolve(const Pending& p) {
  IndexedTriangleShading r;
  for (int k = 0; k < 3; ++k) {
    const std::uint32_t e = entry(p.w[k], p.h[k]);
    // Floats from record i (word 4 i) to entry e (word 4 T + 5 e).
    r.v[k] = static_cast<std::uint32_t>(kRecordWords * (triangles_ - p.triangle) + kVertexWords * e);
  }
  r.material = p.material;
  std::memcpy(block_->data() + kRecordWords * p.triangle, &r, sizeof r);
}

IndexedShadingBuilder::Result IndexedShadingBuilder::finish() {
  if (added_ != triangles_) throw std::logic_error("IndexedShadingBuilder: fewer triangles than announced");
  for (std::size_t i = added_ > kPending ? added_ - kPending : 0; i < added_; ++i) resolve(pending_[i % kPending]);
  std::vector<std::uint64_t>().swap(recent_);
  std::vector<std::uint64_t>().swap(all_);
  Result out;
  out.vertices = vertices_;
  const std::size_t used = 4 * (kRecordWords * triangles_ + kVertexWords * vertices_);
  auto* bytes = reinterpret_cast<unsigned char*>(block_->data());
  if (used >= triangles_ * sizeof(TriangleShading)) {
    // Shared too little to pay: full records, the block gone.
    auto full = std::make_shared<std::vector<TriangleShading>>(triangles_);
    for (std::size_t i = 0; i < triangles_; ++i) (*full)[i] = expand_indexed_shading(bytes, i);
    block_.reset();
    out.bytes = {full->data(), full->size() * sizeof(TriangleShading), sizeof(TriangleShading), full};
    return out;
  }
  // The whole pages past the table go back to the system (a block this large is a mapping of
  // its own; never touched, they are not resident, but a huge page may be).
  const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const auto begin = (reinterpret_cast<std::uintptr_t>(bytes + used) + page - 1) / page * page;
  const auto end = reinterpret_cast<std::uintptr_t>(bytes + 4 * block_->size()) / page * page;
  if (end > begin + (std::uintptr_t{8} << 20)) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_DONTNEED);
  out.indexed = true;
  out.bytes = {bytes, used, sizeof(IndexedTriangleShading), block_};
  return out;
}

TriangleShading expand_indexed_shading(const void* block, std::size_t i) {
  const auto* words = static_cast<const std::uint32_t*>(block);
  IndexedTriangleShading r;
  std::memcpy(&r, words + kRecordWords * i, sizeof r);
  float v[3][5];
  for (int k = 0; k < 3; ++k) std::memcpy(v[k], words + kRecordWords * i + r.v[k], sizeof v[k]);
  TriangleShading s;
  std::memcpy(s.n0, v[0], 12);
  std::memcpy(s.uv0, v[0] + 3, 8);
  std::memcpy(s.n1, v[1], 12);
  std::memcpy(s.uv1, v[1] + 3, 8);
  std::memcpy(s.n2, v[2], 12);
  std::memcpy(s.uv2, v[2] + 3, 8);
  s.material = r.material;
  return s;
}

}  // namespace px
