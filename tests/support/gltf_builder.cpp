#include "support/gltf_builder.h"

namespace px::test {

std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (unsigned(std::uint8_t(bytes[i])) << 16) | (unsigned(std::uint8_t(bytes[i + 1])) << 8) |
                       std::uint8_t(bytes[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += k[(v >> s) & 63];
  }
  if (i < bytes.size()) {
    unsigned v = unsigned(std::uint8_t(bytes[i])) << 16;
    if (i + 1 < bytes.size()) v |= unsigned(std::uint8_t(bytes[i + 1])) << 8;
    out += k[(v >> 18) & 63];
    out += k[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? k[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

int GltfBuilder::accessor(const std::string& bytes, int component, std::size_t count, const char* type) {
  const std::size_t offset = bin.size();
  bin += bytes;
  while (bin.size() % 4) bin.push_back('\0');
  const int view = add("bufferViews", {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes.size()}});
  return add("accessors", {{"bufferView", view}, {"componentType", component}, {"count", count}, {"type", type}});
}

int GltfBuilder::floats(const std::vector<float>& data, const char* type, std::size_t count) {
  return accessor(std::string(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(float)), 5126, count,
                  type);
}

int GltfBuilder::uint16s(const std::vector<std::uint16_t>& data, const char* type, std::size_t count) {
  return accessor(std::string(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(std::uint16_t)), 5123,
                  count, type);
}

int GltfBuilder::add(const char* key, nlohmann::json item) {
  if (!doc.contains(key)) doc[key] = nlohmann::json::array();
  doc[key].push_back(std::move(item));
  return static_cast<int>(doc[key].size()) - 1;
}

std::string GltfBuilder::text() const {
  nlohmann::json d = doc;
  d["buffers"] = nlohmann::json::array(
      {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}});
  return d.dump();
}

}  // namespace px::test
