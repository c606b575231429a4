#include "ParameterImage.hpp"

#include <array>

namespace co::parameter_image {
namespace {

constexpr std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t n = 0; n < 256; ++n) {
    std::uint32_t c = n;
    for (int bit = 0; bit < 8; ++bit) c = (c & 1u) ? 0xEDB8'8320u ^ (c >> 1) : c >> 1;
    table[n] = c;
  }
  return table;
}
constexpr auto kCrcTable = make_crc_table();

void put_u16(std::byte* at, std::uint16_t v) {
  at[0] = static_cast<std::byte>(v & 0xFF);
  at[1] = static_cast<std::byte>(v >> 8);
}
void put_u32(std::byte* at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) at[i] = static_cast<std::byte>((v >> (8 * i)) & 0xFF);
}
std::uint16_t get_u16(const std::byte* at) {
  return static_cast<std::uint16_t>(std::to_integer<std::uint16_t>(at[0]) |
                                    (std::to_integer<std::uint16_t>(at[1]) << 8));
}
std::uint32_t get_u32(const std::byte* at) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= std::to_integer<std::uint32_t>(at[i]) << (8 * i);
  return v;
}

// The CRC covers the whole image except its own four bytes.
std::uint32_t image_crc(std::span<const std::byte> image) {
  std::uint32_t c = 0xFFFF'FFFFu;
  for (std::size_t i = 0; i < image.size(); ++i) {
    if (i >= 8 && i < 12) continue;
    c = kCrcTable[(c ^ std::to_integer<std::uint32_t>(image[i])) & 0xFF] ^ (c >> 8);
  }
  return c ^ 0xFFFF'FFFFu;
}

}  // namespace

std::uint32_t crc32(std::span<const std::byte> bytes) { return crc32(bytes, 0); }

std::uint32_t crc32(std::span<const std::byte> bytes, std::uint32_t previous) {
  std::uint32_t c = previous ^ 0xFFFF'FFFFu;
  for (std::byte b : bytes) c = kCrcTable[(c ^ std::to_integer<std::uint32_t>(b)) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFF'FFFFu;
}

std::size_t encode(std::span<const StoredValue> values, std::span<std::byte, kCapacity> out) {
  const std::size_t count = values.size() < kMaxEntries ? values.size() : kMaxEntries;
  for (std::size_t i = 0; i < count; ++i) {
    std::byte* at = out.data() + kHeaderBytes + i * kEntryBytes;
    put_u16(at, values[i].index);
    at[2] = static_cast<std::byte>(values[i].sub);
    put_u32(at + 3, values[i].raw);
  }
  const std::size_t size = kHeaderBytes + count * kEntryBytes;
  put_u32(out.data(), kMagic);
  put_u16(out.data() + 4, kFormatVersion);
  put_u16(out.data() + 6, static_cast<std::uint16_t>(count));
  put_u32(out.data() + 8, image_crc(out.first(size)));
  return size;
}

namespace {

std::size_t entry_bytes(std::uint16_t version) {
  return version == kFieldsOnlyFormatVersion ? kFieldsOnlyEntryBytes : kEntryBytes;
}

}  // namespace

Check check(std::span<const std::byte> image, std::size_t& entry_count) {
  if (image.empty()) return Check::Empty;
  if (image.size() < kHeaderBytes) return Check::Corrupt;
  const std::uint16_t version = get_u16(image.data() + 4);
  if (get_u32(image.data()) != kMagic ||
      (version != kFormatVersion && version != kFieldsOnlyFormatVersion)) {
    return Check::Corrupt;
  }
  const std::size_t count = get_u16(image.data() + 6);
  if (image.size() != kHeaderBytes + count * entry_bytes(version)) return Check::Corrupt;
  if (get_u32(image.data() + 8) != image_crc(image)) return Check::Corrupt;
  entry_count = count;
  return Check::Valid;
}

StoredValue entry(std::span<const std::byte> image, std::size_t i) {
  const std::uint16_t version = get_u16(image.data() + 4);
  const std::byte* at = image.data() + kHeaderBytes + i * entry_bytes(version);
  if (version == kFieldsOnlyFormatVersion) return {get_u16(at), 0, get_u32(at + 2)};
  return {get_u16(at), std::to_integer<std::uint8_t>(at[2]), get_u32(at + 3)};
}

}  // namespace co::parameter_image
