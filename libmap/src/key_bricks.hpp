// Internal: a set of OcTreeKeys held as bricks of 8 x 8 x 8 voxels, one bit per voxel.
//
// The free voxels of a frame are a million insertions with many repeats, along rays: most
// consecutive keys of a ray fall in the brick of the one before, so an insertion is one bit
// set in a brick already at hand, and a look-up only when the ray leaves it: by hashing, or
// by the brick's offset in a box given to Clear (a frame's rays lie in the box of their
// ends), which is an index read instead of a hash probe. A brick
// is one octree node three levels above the leaves; its bits are numbered in Morton order
// (x, y, z bits interleaved), and the bricks are visited in the Morton order of their
// coordinates, so the keys come out in the Morton order of the whole key: a walk over them
// visits the octree with few cache misses.
#pragma once

#include <octomap/OcTreeKey.h>

#include <algorithm>
#include <cassert>
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

  /// Empties the set; it takes keys anywhere (bricks found by hashing).
  void Clear() {
    ClearBricks();
    dense_.clear();
  }

  /// Empties the set for keys within [lo, hi] (inclusive, per axis) alone: when that box
  /// holds at most kMaxDenseBricks bricks, a brick is found by its offset in the box
  /// instead of by hashing (a ray's walk enters a new brick every few steps). Inserting a
  /// key outside the box is then a programmer error.
  void Clear(const octomap::OcTreeKey& lo, const octomap::OcTreeKey& hi) {
    ClearBricks();
    dense_.clear();
    std::uint64_t count = 1;
    for (int i = 0; i < 3; ++i) {
      box_lo_[i] = lo[i] >> 3;
      box_size_[i] = (hi[i] >> 3) - box_lo_[i] + 1;
      count *= box_size_[i];
    }
    if (count <= kMaxDenseBricks) dense_.assign(count, 0);
  }

  void Insert(const octomap::OcTreeKey& key) {
    const std::uint64_t packed = PackBrick(key);
    if (packed != last_) {
      last_index_ = dense_.empty() ? FindOrAdd(packed) : FindOrAddDense(packed);
      last_ = packed;
    }
    const unsigned bit = Local(key);
    bricks_[last_index_].bits[bit >> 6] |= std::uint64_t{1} << (bit & 63);
  }

  /// Inserts keys like Insert, with the brick of the last key held in registers: for the
  /// long runs of keys in one brick that a ray's walk makes. Valid while nothing else
  /// inserts into the set.
  class Inserter {
   public:
    explicit Inserter(KeyBricks& set) : set_(set) {}
    void operator()(const octomap::OcTreeKey& key) { (*this)(key[0], key[1], key[2]); }
    void operator()(unsigned k0, unsigned k1, unsigned k2) {
      const std::uint64_t packed = PackBrick(k0, k1, k2);
      if (packed != last_) {
        bits_ =
            set_.bricks_[set_.dense_.empty() ? set_.FindOrAdd(packed) : set_.FindOrAddDense(packed)]
                .bits;
        last_ = packed;
      }
      const unsigned bit = Local(k0, k1, k2);
      bits_[bit >> 6] |= std::uint64_t{1} << (bit & 63);
    }

   private:
    KeyBricks& set_;
    std::uint64_t last_ = kNone;
    std::uint64_t* bits_ = nullptr;
  };

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
    ForEachBrickInMortonOrder(
        other, order, [&f](const Brick& brick, const Brick* theirs) { Visit(brick, theirs, f); });
  }

  /// Calls f(brick, theirs) for every brick held, in the Morton order of their coordinates,
  /// with the same brick of `other` (null where it has none, or `other` is null).
  template <typename F>
  void ForEachBrickInMortonOrder(const KeyBricks* other,
                                 std::vector<std::pair<std::uint64_t, std::uint32_t>>& order,
                                 F&& f) const {
    order.clear();
    for (std::uint32_t i = 0; i < bricks_.size(); ++i) order.emplace_back(bricks_[i].code, i);
    std::sort(order.begin(), order.end());
    for (const auto& [code, index] : order) {
      f(bricks_[index], other != nullptr ? other->Find(PackFromCode(code)) : nullptr);
    }
  }

  /// Calls f(code, mine, theirs) for every brick held here or in `other`, in the Morton order
  /// of their coordinates (`code`), with this set's brick and the same brick of `other` (null
  /// where a set has none).
  template <typename F>
  void ForEachBrickOfEitherInMortonOrder(
      const KeyBricks& other, std::vector<std::pair<std::uint64_t, std::uint32_t>>& order,
      F&& f) const {
    assert(bricks_.size() < (std::size_t{1} << 31) &&
           other.bricks_.size() < (std::size_t{1} << 31));
    order.clear();
    for (std::uint32_t i = 0; i < bricks_.size(); ++i) order.emplace_back(bricks_[i].code, 2 * i);
    for (std::uint32_t i = 0; i < other.bricks_.size(); ++i) {
      order.emplace_back(other.bricks_[i].code, 2 * i + 1);
    }
    std::sort(order.begin(), order.end());
    for (std::size_t k = 0; k < order.size();) {
      const std::uint64_t code = order[k].first;
      const Brick* mine = nullptr;
      const Brick* theirs = nullptr;
      for (; k < order.size() && order[k].first == code; ++k) {
        const std::uint32_t i = order[k].second;
        if (i % 2 == 0) {
          mine = &bricks_[i / 2];
        } else {
          theirs = &other.bricks_[i / 2];
        }
      }
      f(code, mine, theirs);
    }
  }

  /// The brick of Morton code `code` (Brick::code), or null.
  const Brick* BrickOf(std::uint64_t code) const { return Find(PackFromCode(code)); }

  /// The key of the first voxel of the brick of Morton code `code`.
  static octomap::OcTreeKey BaseKeyOf(std::uint64_t code) {
    return octomap::OcTreeKey(static_cast<octomap::key_type>(Compact3(code) << 3),
                              static_cast<octomap::key_type>(Compact3(code >> 1) << 3),
                              static_cast<octomap::key_type>(Compact3(code >> 2) << 3));
  }

  /// The key of the brick's first voxel (its local coordinates 0, 0, 0).
  static octomap::OcTreeKey BaseKey(const Brick& brick) { return BaseKeyOf(brick.code); }
  /// The key of the voxel of local Morton code `bit` in the brick whose first key is `base`.
  static octomap::OcTreeKey KeyOf(const octomap::OcTreeKey& base, unsigned bit) {
    return octomap::OcTreeKey(static_cast<octomap::key_type>(base[0] | Compact3(bit)),
                              static_cast<octomap::key_type>(base[1] | Compact3(bit >> 1)),
                              static_cast<octomap::key_type>(base[2] | Compact3(bit >> 2)));
  }

  /// Adds the keys of `other`.
  void Merge(const KeyBricks& other) {
    for (const Brick& b : other.bricks_) {
      const std::uint64_t packed = PackFromCode(b.code);
      Brick& mine = bricks_[dense_.empty() ? FindOrAdd(packed) : FindOrAddDense(packed)];
      for (int w = 0; w < 8; ++w) mine.bits[w] |= b.bits[w];
    }
    last_ = kNone;
  }

 private:
  friend class KeyBitBox;
  // A hash slot: a packed brick coordinate (+1; 0 marks a free slot) and its brick's index.
  struct Slot {
    std::uint64_t packed = 0;
    std::uint32_t index = 0;
  };
  static constexpr std::uint64_t kNone = 0;
  // 16 MiB of brick indices at most (a 20 m range at 0.1 m voxels needs about 0.5 MiB).
  static constexpr std::uint64_t kMaxDenseBricks = std::uint64_t{1} << 22;

  // Forgets the bricks; the caller then drops or remakes the dense index (slots_ is only
  // written while hashing, so it is clean after a dense frame).
  void ClearBricks() {
    if (dense_.empty()) std::fill(slots_.begin(), slots_.end(), Slot{});
    bricks_.clear();
    last_ = kNone;
    last_index_ = 0;
  }

  // Brick coordinates (13 bits each) packed into 39 bits, + 1.
  static std::uint64_t PackBrick(const octomap::OcTreeKey& k) {
    return PackBrick(k[0], k[1], k[2]);
  }
  static std::uint64_t PackBrick(unsigned k0, unsigned k1, unsigned k2) {
    return (static_cast<std::uint64_t>(k0 >> 3) | static_cast<std::uint64_t>(k1 >> 3) << 13 |
            static_cast<std::uint64_t>(k2 >> 3) << 26) +
           1;
  }
  static std::uint64_t PackFromCode(std::uint64_t code) {
    return (static_cast<std::uint64_t>(Compact3(code)) |
            static_cast<std::uint64_t>(Compact3(code >> 1)) << 13 |
            static_cast<std::uint64_t>(Compact3(code >> 2)) << 26) +
           1;
  }
  // The voxel's Morton code within its brick (9 bits).
  static unsigned Local(const octomap::OcTreeKey& k) { return Local(k[0], k[1], k[2]); }
  static unsigned Local(unsigned k0, unsigned k1, unsigned k2) {
    static constexpr unsigned kSpread[8] = {0, 1, 8, 9, 64, 65, 72, 73};  // Spread3(0..7)
    return kSpread[k0 & 7u] | kSpread[k1 & 7u] << 1 | kSpread[k2 & 7u] << 2;
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
    if (!dense_.empty()) {
      --packed;
      for (int i = 0; i < 3; ++i) {
        const std::uint32_t b = static_cast<std::uint32_t>(packed >> (13 * i) & 0x1fff);
        if (b < box_lo_[i] || b - box_lo_[i] >= box_size_[i]) return nullptr;
      }
      const std::uint32_t slot = dense_[DenseOffset(packed + 1)];
      return slot == 0 ? nullptr : &bricks_[slot - 1];
    }
    if (slots_.empty()) return nullptr;
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = Hash(packed) & mask;; i = (i + 1) & mask) {
      if (slots_[i].packed == packed) return &bricks_[slots_[i].index];
      if (slots_[i].packed == 0) return nullptr;
    }
  }

  // The offset of a brick (packed) in the dense box.
  std::size_t DenseOffset(std::uint64_t packed) const {
    --packed;
    const std::uint32_t b[3] = {static_cast<std::uint32_t>(packed & 0x1fff),
                                static_cast<std::uint32_t>(packed >> 13 & 0x1fff),
                                static_cast<std::uint32_t>(packed >> 26 & 0x1fff)};
    for (int i = 0; i < 3; ++i) assert(b[i] >= box_lo_[i] && b[i] - box_lo_[i] < box_size_[i]);
    return (static_cast<std::size_t>(b[2] - box_lo_[2]) * box_size_[1] + (b[1] - box_lo_[1])) *
               box_size_[0] +
           (b[0] - box_lo_[0]);
  }

  std::uint32_t FindOrAddDense(std::uint64_t packed) {
    std::uint32_t& slot = dense_[DenseOffset(packed)];  // index + 1; 0: none yet
    if (slot == 0) {
      Brick brick;
      brick.code = Code(packed);
      bricks_.push_back(brick);
      slot = static_cast<std::uint32_t>(bricks_.size());
    }
    return slot - 1;
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
  std::vector<std::uint32_t> dense_;       // with a box: brick index + 1 by offset in it (0: none)
  std::uint32_t box_lo_[3] = {0, 0, 0};    // the box's first brick coordinates (key >> 3)
  std::uint32_t box_size_[3] = {0, 0, 0};  // and its size in bricks
  std::vector<Brick> bricks_;
  std::uint64_t last_ = kNone;  // the brick of the last insertion (packed), and its index
  std::uint32_t last_index_ = 0;
};

/// Keys within a box of them, one bit each, numbered x fastest (a KeyLayout of ray_keys.hpp):
/// a ray's walk steps by adding an axis' stride to the number, and sets its key with one or.
/// KeyBricks finds a brick by its index in the box at every brick a ray enters and adds it
/// when it is new, and which of these comes next is what the processor cannot guess. The
/// keys then go into a KeyBricks set (MoveInto).
class KeyBitBox {
 public:
  /// 16 MiB of bits at most (a 20 m range at 0.1 m voxels needs about 3 MiB).
  static constexpr std::int64_t kMaxKeys = std::int64_t{1} << 27;

  /// Empties the box for keys within [lo, hi] (inclusive, per axis), with a margin of one
  /// key on every side. False, and the box unusable until the next Reset, when that holds
  /// more than kMaxKeys keys.
  bool Reset(const octomap::OcTreeKey& lo, const octomap::OcTreeKey& hi) {
    if (dirty_) std::fill(words_.begin(), words_.end(), 0);
    dirty_ = false;
    // Bricks whole (8 keys a side from a multiple of 8), rows whole words.
    std::int64_t size[3];
    for (int i = 0; i < 3; ++i) {
      lo_[i] = std::max<std::int64_t>(0, lo[i] - 1) & ~std::int64_t{7};
      size[i] = ((hi[i] + 1 - lo_[i]) | 7) + 1;
    }
    size[0] = (size[0] + 63) & ~std::int64_t{63};
    if (size[0] * size[1] * size[2] > kMaxKeys) {
      size_[0] = size_[1] = size_[2] = 0;
      return false;
    }
    for (int i = 0; i < 3; ++i) size_[i] = size[i];
    const std::size_t words = static_cast<std::size_t>(size[0] * size[1] * size[2] / 64);
    if (words_.size() < words) words_.resize(words, 0);
    dirty_ = true;  // until MoveInto empties it
    return true;
  }

  /// How the box numbers its keys: (k0 - lo0) + size0 ((k1 - lo1) + size1 (k2 - lo2)).
  void Layout(std::int64_t (&lo)[3], std::int64_t (&stride)[3]) const {
    for (int i = 0; i < 3; ++i) lo[i] = lo_[i];
    stride[0] = 1;
    stride[1] = size_[0];
    stride[2] = size_[0] * size_[1];
  }

  /// Sets the key of number n (which lies in the box).
  void Set(std::int64_t n) {
    assert(n >= 0 && n < size_[0] * size_[1] * size_[2]);  // a refused box holds none
    words_[static_cast<std::size_t>(n >> 6)] |= std::uint64_t{1} << (n & 63);
  }

  /// Adds the keys held to `set` and empties the box.
  void MoveInto(KeyBricks& set) {
    // A brick's 64 rows of 8 keys along x, each a byte of the box's rows, spread to its
    // Morton bits: x's low half to bits {0, 1, 8, 9} of one word, its high half the same
    // in the next, both shifted by the row's y and z bits.
    static constexpr std::uint64_t kSpreadNibble[16] = {0x000, 0x001, 0x002, 0x003, 0x100, 0x101,
                                                        0x102, 0x103, 0x200, 0x201, 0x202, 0x203,
                                                        0x300, 0x301, 0x302, 0x303};
    const std::int64_t row_words = size_[0] / 64;
    const std::int64_t bricks_x = size_[0] / 8;
    std::vector<std::uint64_t>& bits = brick_row_;  // one row of bricks along x, 8 words each
    bits.assign(static_cast<std::size_t>(bricks_x) * 8, 0);
    std::vector<std::int32_t>& touched = touched_;
    for (std::int64_t zb = 0; zb < size_[2] / 8; ++zb) {
      for (std::int64_t yb = 0; yb < size_[1] / 8; ++yb) {
        touched.clear();
        for (unsigned zz = 0; zz < 8; ++zz) {
          for (unsigned yy = 0; yy < 8; ++yy) {
            const unsigned local = KeyBricks::Local(0, yy, zz);
            const unsigned word = local >> 6, shift = local & 63;
            std::uint64_t* row = &words_[static_cast<std::size_t>(
                ((zb * 8 + zz) * size_[1] + (yb * 8 + yy)) * row_words)];
            for (std::int64_t w = 0; w < row_words; ++w) {
              std::uint64_t v = row[w];
              if (v == 0) continue;
              row[w] = 0;
              for (; v != 0; v &= ~(std::uint64_t{0xff} << (__builtin_ctzll(v) & ~7))) {
                const unsigned byte_at = static_cast<unsigned>(__builtin_ctzll(v)) >> 3;
                const unsigned byte = static_cast<unsigned>(v >> (8 * byte_at) & 0xff);
                const std::int64_t bx = w * 8 + byte_at;
                std::uint64_t* b = &bits[static_cast<std::size_t>(bx) * 8];
                if ((b[0] | b[1] | b[2] | b[3] | b[4] | b[5] | b[6] | b[7]) == 0) {
                  touched.push_back(static_cast<std::int32_t>(bx));
                }
                b[word] |= kSpreadNibble[byte & 15] << shift;
                b[word + 1] |= kSpreadNibble[byte >> 4] << shift;
              }
            }
          }
        }
        for (const std::int32_t bx : touched) {
          std::uint64_t* b = &bits[static_cast<std::size_t>(bx) * 8];
          const std::uint64_t packed = KeyBricks::PackBrick(static_cast<unsigned>(lo_[0] + 8 * bx),
                                                            static_cast<unsigned>(lo_[1] + 8 * yb),
                                                            static_cast<unsigned>(lo_[2] + 8 * zb));
          KeyBricks::Brick& mine =
              set.bricks_[set.dense_.empty() ? set.FindOrAdd(packed) : set.FindOrAddDense(packed)];
          for (int k = 0; k < 8; ++k) {
            mine.bits[k] |= b[k];
            b[k] = 0;
          }
        }
      }
    }
    set.last_ = KeyBricks::kNone;
    dirty_ = false;
  }

 private:
  std::vector<std::uint64_t> words_;  // the box's bits, x fastest, rows of whole words
  std::int64_t lo_[3] = {0, 0, 0};    // the box's first key (multiples of 8)
  std::int64_t size_[3] = {0, 0, 0};  // its size in keys (x a multiple of 64, y and z of 8)
  bool dirty_ = false;                // reset and not emptied since: keys may be set
  std::vector<std::uint64_t> brick_row_;
  std::vector<std::int32_t> touched_;
};

}  // namespace cairn::map::internal
