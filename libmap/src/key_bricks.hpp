// Internal: a set of OcTreeKeys held as bricks of 8 x 8 x 8 voxels, one bit per voxel.
//
// The free voxels of a frame are a million insertions with many repeats, along rays: most
// consecutive keys of a ray fall in the brick of the one before, so an insertion is one bit
// set in a brick already at hand, and a hash look-up only when the ray leaves it. A brick
// is one octree node three levels above the leaves; its bits are numbered in Morton order
// (x, y, z bits interleaved), and the bricks are visited in the Morton order of their
// coordinates, so the keys come out in the Morton order of the whole key: a walk over them
// visits the octree with few cache misses.
#pragma once

#include <octomap/OcTreeKey.h>

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace cairn::map::internal {

class KeyBricks {
 public:
  struct Brick {
    std::uint64_t code = 0;  // Morton code of the brick's coordinates (key >> 3)
    std::uint64_t bits[8] = {0, 0, 0, 0, 0, 0, 0, 0};  // bit b: the voxel of local Morton code b
  };

  void Clear() {
    std::fill(slots_.begin(), slots_.end(), Slot{});
    bricks_.clear();
    last_ = kNone;
    last_index_ = 0;
  }

  void Insert(const octomap::OcTreeKey& key) {
    const std::uint64_t packed = PackBrick(key);
    if (packed != last_) {
      last_index_ = FindOrAdd(packed);
      last_ = packed;
    }
    const unsigned bit = Local(key);
    bricks_[last_index_].bits[bit >> 6] |= std::uint64_t{1} << (bit & 63);
  }

  bool Contains(const octomap::OcTreeKey& key) const {
    const Brick* brick = Find(PackBrick(key));
    const unsigned bit = Local(key);
    return brick != nullptr && (brick->bits[bit >> 6] >> (bit & 63) & 1) != 0;
  }

  /// The number of keys held (counts bits: not for inner loops).
  std::size_t size() const {
    std::size_t n = 0;
    for (const Brick& b : bricks_) {
      for (const std::uint64_t w : b.bits) n += static_cast<std::size_t>(__builtin_popcountll(w));
    }
    return n;
  }

  /// Calls f(key) for every key held, brick after brick in the order they were first
  /// inserted into.
  template <typename F>
  void ForEach(F&& f) const {
    for (const Brick& brick : bricks_) Visit(brick, nullptr, f);
  }

  /// Calls f(key, in_other) for every key held, in the Morton order of the keys, with
  /// whether `other` (may be null) holds it too. `order` is a reused buffer.
  template <typename F>
  void ForEachInMortonOrder(const KeyBricks* other,
                            std::vector<std::pair<std::uint64_t, std::uint32_t>>& order,
                            F&& f) const {
    order.clear();
    for (std::uint32_t i = 0; i < bricks_.size(); ++i) order.emplace_back(bricks_[i].code, i);
    std::sort(order.begin(), order.end());
    for (const auto& [code, index] : order) {
      const Brick& brick = bricks_[index];
      Visit(brick, other != nullptr ? other->Find(PackFromCode(code)) : nullptr, f);
    }
  }

  /// Adds the keys of `other`.
  void Merge(const KeyBricks& other) {
    for (const Brick& b : other.bricks_) {
      Brick& mine = bricks_[FindOrAdd(PackFromCode(b.code))];
      for (int w = 0; w < 8; ++w) mine.bits[w] |= b.bits[w];
    }
    last_ = kNone;
  }

 private:
  // A hash slot: a packed brick coordinate (+1; 0 marks a free slot) and its brick's index.
  struct Slot {
    std::uint64_t packed = 0;
    std::uint32_t index = 0;
  };
  static constexpr std::uint64_t kNone = 0;

  // Brick coordinates (13 bits each) packed into 39 bits, + 1.
  static std::uint64_t PackBrick(const octomap::OcTreeKey& k) {
    return (static_cast<std::uint64_t>(k[0] >> 3) | static_cast<std::uint64_t>(k[1] >> 3) << 13 |
            static_cast<std::uint64_t>(k[2] >> 3) << 26) +
           1;
  }
  static std::uint64_t PackFromCode(std::uint64_t code) {
    return (static_cast<std::uint64_t>(Compact3(code)) |
            static_cast<std::uint64_t>(Compact3(code >> 1)) << 13 |
            static_cast<std::uint64_t>(Compact3(code >> 2)) << 26) +
           1;
  }
  // The voxel's Morton code within its brick (9 bits).
  static unsigned Local(const octomap::OcTreeKey& k) {
    return Spread3(k[0] & 7u) | Spread3(k[1] & 7u) << 1 | Spread3(k[2] & 7u) << 2;
  }
  // Every bit of v (up to 21) to every third bit, and back.
  static std::uint64_t Spread3(std::uint64_t v) {
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
  }
  static std::uint32_t Compact3(std::uint64_t v) {
    v &= 0x1249249249249249ULL;
    v = (v ^ (v >> 2)) & 0x10c30c30c30c30c3ULL;
    v = (v ^ (v >> 4)) & 0x100f00f00f00f00fULL;
    v = (v ^ (v >> 8)) & 0x1f0000ff0000ffULL;
    v = (v ^ (v >> 16)) & 0x1f00000000ffffULL;
    v = (v ^ (v >> 32)) & 0x1fffffULL;
    return static_cast<std::uint32_t>(v);
  }
  static std::uint64_t Code(std::uint64_t packed) {  // Morton code of packed brick coordinates
    --packed;
    return Spread3(packed & 0x1fff) | Spread3((packed >> 13) & 0x1fff) << 1 |
           Spread3((packed >> 26) & 0x1fff) << 2;
  }
  // f(key, in_other) for the keys of one brick in Morton order; `other` is the same brick of
  // another set, or null.
  template <typename F>
  static void Visit(const Brick& brick, const Brick* other, F& f) {
    const std::uint32_t bx = Compact3(brick.code), by = Compact3(brick.code >> 1),
                        bz = Compact3(brick.code >> 2);
    for (int w = 0; w < 8; ++w) {
      std::uint64_t word = brick.bits[w];
      const std::uint64_t theirs = other != nullptr ? other->bits[w] : 0;
      while (word != 0) {
        const unsigned b = static_cast<unsigned>(__builtin_ctzll(word));
        word &= word - 1;
        const unsigned bit = static_cast<unsigned>(w * 64) + b;
        f(octomap::OcTreeKey(static_cast<octomap::key_type>(bx << 3 | Compact3(bit)),
                             static_cast<octomap::key_type>(by << 3 | Compact3(bit >> 1)),
                             static_cast<octomap::key_type>(bz << 3 | Compact3(bit >> 2))),
          (theirs >> b & 1) != 0);
      }
    }
  }

  static std::size_t Hash(std::uint64_t x) {  // splitmix64's finaliser
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return static_cast<std::size_t>(x);
  }

  const Brick* Find(std::uint64_t packed) const {
    if (slots_.empty()) return nullptr;
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = Hash(packed) & mask;; i = (i + 1) & mask) {
      if (slots_[i].packed == packed) return &bricks_[slots_[i].index];
      if (slots_[i].packed == 0) return nullptr;
    }
  }

  std::uint32_t FindOrAdd(std::uint64_t packed) {
    if (2 * (bricks_.size() + 1) > slots_.size()) Grow();
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = Hash(packed) & mask;; i = (i + 1) & mask) {
      if (slots_[i].packed == packed) return slots_[i].index;
      if (slots_[i].packed == 0) {
        Brick brick;
        brick.code = Code(packed);
        slots_[i] = {packed, static_cast<std::uint32_t>(bricks_.size())};
        bricks_.push_back(brick);
        return slots_[i].index;
      }
    }
  }

  void Grow() {
    slots_.assign(std::max<std::size_t>(1024, slots_.size() * 2), Slot{});
    const std::size_t mask = slots_.size() - 1;
    for (std::uint32_t b = 0; b < bricks_.size(); ++b) {
      const std::uint64_t packed = PackFromCode(bricks_[b].code);
      std::size_t i = Hash(packed) & mask;
      while (slots_[i].packed != 0) i = (i + 1) & mask;
      slots_[i] = {packed, b};
    }
  }

  std::vector<Slot> slots_;
  std::vector<Brick> bricks_;
  std::uint64_t last_ = kNone;  // the brick of the last insertion (packed), and its index
  std::uint32_t last_index_ = 0;
};

}  // namespace cairn::map::internal
