#include "render/device_layout_cache.h"

#include "bvh/bvh_cache.h"
#include "io/atomic_file.h"
#include "io/content_hash.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string_view>

namespace px {
namespace {

constexpr char kMagic[8] = {'P', 'X', 'D', 'L', 'A', 'Y', '0', '1'};
// 2: shading_records, shading_bytes; 3: wide leaf slots hold block | count << 29.
constexpr std::uint64_t kFormatVersion = 3;
constexpr std::size_t kPage = 4096;
// The start's sample of the payload: the first kSampleBytes of every sample_stride() bytes, at
// most kSamples of them. Few, since a mapped file's touched pages count as the process's memory,
// and on kernels that cache files in large folios (up to 2 MiB) one touched byte maps its whole
// folio: one sample per MiB had made the whole file resident before the first frame.
constexpr std::size_t kSampleBytes = kPage, kSamples = 64;
std::size_t sample_stride(std::size_t payload_bytes) {
  const std::size_t per_sample = (payload_bytes + kSamples - 1) / kSamples;
  return std::max(kPage, (per_sample + kPage - 1) / kPage * kPage);
}
#ifndef PX_DEVICE_LAYOUT_SHA
#define PX_DEVICE_LAYOUT_SHA "unknown"
#endif
// SHA-1 of the sources the layout depends on (builder, collapser, validator, device layout; set
// by CMake): a rebuilt parallax with any of them changed never maps an old file.
constexpr const char* kSourcesSha = PX_DEVICE_LAYOUT_SHA;

// Fixed-size header, every field 8 bytes wide (no padding on any platform we build for).
struct DeviceLayoutHeader {
  char magic[8];
  std::uint64_t format, key, layout;
  std::uint64_t node_size, triangle_size, shading_size, leaf_block_size;  // sizeof the layouts
  std::uint64_t scene_triangles;
  std::uint64_t nodes_offset, node_bytes, triangles_offset, triangle_count, shading_offset, shading_count;
  std::uint64_t file_bytes;
  std::uint64_t layout_nodes;
  std::uint64_t shading_records, shading_bytes;  // ShadingRecords; the section's bytes
  std::uint64_t stat_leaf_triangles, stat_nodes, stat_depth, stat_split_budget_exceeded, stat_split_calls;
  double stat_build_ms, stat_collapse_ms, stat_sah_cost;
  std::uint64_t sample_checksum;   // kSampleBytes of every sample_stride() of the payload
  std::uint64_t payload_checksum;  // the whole payload (verify_payload)
  std::uint64_t header_checksum;   // every field above
};
static_assert(sizeof(DeviceLayoutHeader) <= kPage, "the header fits its page");

std::size_t round_up(std::size_t n) { return (n + kPage - 1) / kPage * kPage; }

std::uint64_t header_checksum(const DeviceLayoutHeader& h) {
  return content_hash(&h, offsetof(DeviceLayoutHeader, header_checksum), 0x5844'4c41'5948'4452ull);
}

// The payload runs from the first section to the end of the file.
std::uint64_t sample_checksum(const unsigned char* payload, std::size_t n) {
  ContentHash h(1);
  const std::size_t stride = sample_stride(n);
  for (std::size_t off = 0; off < n; off += stride) h.bytes(payload + off, std::min(kSampleBytes, n - off));
  return h.digest();
}

std::uint64_t payload_checksum(const unsigned char* payload, std::size_t n) { return content_hash(payload, n, 2); }

}  // namespace

const char* to_string(ShadingRecords records) {
  switch (records) {
    case ShadingRecords::Full: return "full";
    case ShadingRecords::Flat: return "flat";
    case ShadingRecords::Indexed: return "indexed";
  }
  return "?";
}

std::size_t record_size(ShadingRecords records) {
  return records == ShadingRecords::Full   ? sizeof(TriangleShading)
         : records == ShadingRecords::Flat ? sizeof(FlatTriangleShading)
                                           : sizeof(IndexedTriangleShading);
}

std::uint64_t scene_content_key(const Scene& scene) {
  ContentHash h;
  h.value(static_cast<std::uint64_t>(scene.triangles.size()));
  // SceneTriangle is 25 four-byte fields with no padding: its bytes are its values.
  static_assert(sizeof(SceneTriangle) == 100, "SceneTriangle has no padding");
  h.bytes(scene.triangles.data(), scene.triangles.size() * sizeof(SceneTriangle));
  for (const Material& m : scene.materials) {
    const std::uint32_t flags =
        (m.alpha_texture >= 0 ? PX_TRI_ALPHA_TESTED : 0u) | (m.is_emissive() ? PX_TRI_EMISSIVE : 0u);
    h.value(flags);
  }
  return h.digest();
}

std::uint64_t device_layout_key(std::uint64_t content_key, BvhLayout layout, const BvhBuildOptions& options) {
  ContentHash h;
  h.value(kFormatVersion);
  h.bytes(kSourcesSha, std::strlen(kSourcesSha));
  h.value(content_key);
  h.value(static_cast<std::uint32_t>(bvh_layout_width(layout)));
  h.value(static_cast<std::uint8_t>(options.spatial_splits));
  h.value(options.max_leaf_size);
  h.value(options.split_calls_per_triangle);
  h.value(static_cast<std::uint64_t>(options.split_trial_triangles));
  h.value(options.split_min_gain);
  h.value(static_cast<std::uint64_t>(options.split_trial_max_sample));
  h.value(static_cast<std::uint64_t>(options.block_leaves_from));
  return h.digest();
}

MappedDeviceLayout::~MappedDeviceLayout() {
  if (base_) munmap(base_, length_);
}

bool MappedDeviceLayout::verify_payload() const {
  const auto* p = static_cast<const unsigned char*>(base_);
  return payload_checksum(p + nodes_offset_, length_ - nodes_offset_) == payload_checksum_;
}

std::string DeviceLayoutCache::default_dir() { return BvhCache::default_dir(); }

std::string DeviceLayoutCache::path_for(std::uint64_t key) const {
  char name[48];
  std::snprintf(name, sizeof name, "device-layout-%016llx.bin", static_cast<unsigned long long>(key));
  return dir_ + "/" + name;
}

std::shared_ptr<const MappedDeviceLayout> DeviceLayoutCache::open(std::uint64_t content_key, BvhLayout layout,
                                                                  const BvhBuildOptions& options,
                                                                  std::size_t scene_triangles) const {
  if (dir_.empty()) return nullptr;
  const std::uint64_t key = device_layout_key(content_key, layout, options);
  const std::string path = path_for(key);
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return nullptr;
  struct stat st {};
  DeviceLayoutHeader h{};
  const bool readable = fstat(fd, &st) == 0 && static_cast<std::size_t>(st.st_size) >= kPage &&
                        pread(fd, &h, sizeof h, 0) == static_cast<ssize_t>(sizeof h);
  if (!readable) {
    ::close(fd);
    return nullptr;
  }
  const std::size_t length = static_cast<std::size_t>(st.st_size);
  // Every field is checked before anything is mapped: a file of another scene, layout, format or
  // build, cut short or grown, is a miss.
  const bool header_ok =
      std::memcmp(h.magic, kMagic, sizeof kMagic) == 0 && h.format == kFormatVersion &&
      h.header_checksum == header_checksum(h) && h.key == key &&
      h.layout == static_cast<std::uint64_t>(bvh_layout_width(layout)) &&
      h.node_size == (layout == BvhLayout::Binary ? sizeof(BvhNode) : 4) &&
      (h.triangle_size == sizeof(BvhTriangle) ||
       (h.triangle_size == sizeof(BvhLeafRef) && (layout == BvhLayout::Wide4 || layout == BvhLayout::Wide8))) &&
      h.shading_records <= static_cast<std::uint64_t>(ShadingRecords::Indexed) &&
      h.shading_size == record_size(static_cast<ShadingRecords>(h.shading_records)) &&
      h.shading_bytes >= h.shading_count * h.shading_size &&
      (h.shading_records == static_cast<std::uint64_t>(ShadingRecords::Indexed)
           ? (h.shading_bytes - h.shading_count * h.shading_size) % sizeof(ShadingVertex) == 0
           : h.shading_bytes == h.shading_count * h.shading_size) &&
      h.leaf_block_size == sizeof(BvhLeafBlock) && h.scene_triangles == scene_triangles &&
      h.shading_count == scene_triangles && h.file_bytes == length && h.nodes_offset == kPage && h.node_bytes > 0 &&
      h.triangle_count > 0 && h.triangles_offset == round_up(h.nodes_offset + h.node_bytes) &&
      h.triangle_count <= (length / h.triangle_size) &&
      h.shading_offset == round_up(h.triangles_offset + h.triangle_count * h.triangle_size) &&
      h.shading_offset + h.shading_bytes == length;
  if (!header_ok) {
    ::close(fd);
    return nullptr;
  }
  void* base = mmap(nullptr, length, PROT_READ, MAP_PRIVATE, fd, 0);
  ::close(fd);  // the mapping keeps the file
  if (base == MAP_FAILED) return nullptr;
  std::shared_ptr<MappedDeviceLayout> m(new MappedDeviceLayout());
  m->base_ = base;
  m->length_ = length;
  m->path_ = path;
  const auto* payload = static_cast<const unsigned char*>(base) + h.nodes_offset;
  if (sample_checksum(payload, length - h.nodes_offset) != h.sample_checksum) return nullptr;  // unmaps
  m->layout_ = layout;
  m->layout_nodes_ = h.layout_nodes;
  m->nodes_offset_ = h.nodes_offset;
  m->node_bytes_ = h.node_bytes;
  m->triangles_offset_ = h.triangles_offset;
  m->triangle_count_ = h.triangle_count;
  m->triangle_size_ = h.triangle_size;
  m->shading_offset_ = h.shading_offset;
  m->shading_count_ = h.shading_count;
  m->shading_size_ = h.shading_size;
  m->shading_bytes_ = h.shading_bytes;
  m->shading_records_ = static_cast<ShadingRecords>(h.shading_records);
  m->payload_checksum_ = h.payload_checksum;
  BvhBuildStats& s = m->stats_;
  s.scene_triangles = h.scene_triangles;
  s.leaf_triangles = h.stat_leaf_triangles;
  s.nodes = h.stat_nodes;
  s.depth = static_cast<int>(h.stat_depth);
  s.split_budget_exceeded = h.stat_split_budget_exceeded != 0;
  s.split_calls = h.stat_split_calls;
  s.build_ms = h.stat_build_ms;
  s.collapse_ms = h.stat_collapse_ms;
  s.sah_cost = h.stat_sah_cost;
  return m;
}

std::string DeviceLayoutCache::store(std::uint64_t content_key, const BvhBuildOptions& options,
                                     std::size_t scene_triangles, const DeviceLayoutParts& parts,
                                     std::string* why) const {
  if (dir_.empty()) {
    if (why) *why = "no cache folder";
    return "";
  }
  try {
    if (!parts.nodes || parts.node_bytes == 0 || !parts.triangles || parts.triangle_count == 0 ||
        (parts.triangle_size != sizeof(BvhTriangle) && parts.triangle_size != sizeof(BvhLeafRef)) || !parts.shading ||
        parts.shading_count != scene_triangles || parts.shading_size != record_size(parts.shading_records) ||
        (parts.shading_bytes != 0 && parts.shading_bytes < parts.shading_count * parts.shading_size))
      throw std::invalid_argument("incomplete device layout");
    const std::size_t shading_bytes =
        parts.shading_bytes != 0 ? parts.shading_bytes : parts.shading_count * parts.shading_size;
    std::filesystem::create_directories(dir_);
    DeviceLayoutHeader h{};
    std::memcpy(h.magic, kMagic, sizeof kMagic);
    h.format = kFormatVersion;
    h.key = device_layout_key(content_key, parts.layout, options);
    h.layout = static_cast<std::uint64_t>(bvh_layout_width(parts.layout));
    h.node_size = parts.layout == BvhLayout::Binary ? sizeof(BvhNode) : 4;
    h.triangle_size = parts.triangle_size;
    h.shading_size = parts.shading_size;
    h.leaf_block_size = sizeof(BvhLeafBlock);
    h.scene_triangles = scene_triangles;
    h.nodes_offset = kPage;
    h.node_bytes = parts.node_bytes;
    h.triangles_offset = round_up(h.nodes_offset + h.node_bytes);
    h.triangle_count = parts.triangle_count;
    h.shading_offset = round_up(h.triangles_offset + h.triangle_count * h.triangle_size);
    h.shading_count = parts.shading_count;
    h.shading_records = static_cast<std::uint64_t>(parts.shading_records);
    h.shading_bytes = shading_bytes;
    h.file_bytes = h.shading_offset + shading_bytes;
    h.layout_nodes = parts.layout_nodes;
    h.stat_leaf_triangles = parts.stats.leaf_triangles;
    h.stat_nodes = parts.stats.nodes;
    h.stat_depth = static_cast<std::uint64_t>(parts.stats.depth);
    h.stat_split_budget_exceeded = parts.stats.split_budget_exceeded;
    h.stat_split_calls = parts.stats.split_calls;
    h.stat_build_ms = parts.stats.build_ms;
    h.stat_collapse_ms = parts.stats.collapse_ms;
    h.stat_sah_cost = parts.stats.sah_cost;
    // The payload as it will lie in the file, section by section with its zero padding, goes
    // through both checksums in one pass.
    const std::string zeros(kPage, '\0');
    struct Piece {
      const void* data;
      std::size_t bytes;
    };
    const Piece pieces[] = {
        {parts.nodes, parts.node_bytes},
        {zeros.data(), h.triangles_offset - (h.nodes_offset + h.node_bytes)},
        {parts.triangles, h.triangle_count * h.triangle_size},
        {zeros.data(), h.shading_offset - (h.triangles_offset + h.triangle_count * h.triangle_size)},
        {parts.shading, shading_bytes}};
    ContentHash full(2), sample(1);
    const std::size_t stride = sample_stride(h.file_bytes - h.nodes_offset);
    std::size_t at = 0;  // payload offset
    for (const Piece& piece : pieces) {
      full.bytes(piece.data, piece.bytes);
      const auto* p = static_cast<const unsigned char*>(piece.data);
      for (std::size_t i = 0; i < piece.bytes;) {
        const std::size_t in_stride = (at + i) % stride;
        const std::size_t n = in_stride < kSampleBytes ? std::min(kSampleBytes - in_stride, piece.bytes - i)
                                                       : std::min(stride - in_stride, piece.bytes - i);
        if (in_stride < kSampleBytes) sample.bytes(p + i, n);
        i += n;
      }
      at += piece.bytes;
    }
    h.payload_checksum = full.digest();
    h.sample_checksum = sample.digest();
    h.header_checksum = header_checksum(h);
    const std::string path = path_for(h.key);
    AtomicFileWriter out(path);
    std::string first(kPage, '\0');
    std::memcpy(first.data(), &h, sizeof h);
    out.write(first);
    for (const Piece& piece : pieces) out.write({static_cast<const char*>(piece.data), piece.bytes});
    out.commit();
    return path;
  } catch (const std::exception& e) {
    if (why) *why = e.what();
    return "";
  }
}

}  // namespace px
