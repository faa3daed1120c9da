// Sparse two-level map from 8x8-pixel tiles to per-tile state, allocated on
// first touch: memory follows what the scene touches, not width x height.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

namespace ropsim {

template <class Tile>
class TileMap {
 public:
  static constexpr int kTileShift = 3;  ///< 8 x 8 pixels per tile
  static constexpr int kTileSide = 1 << kTileShift;
  static constexpr int kDirShift = 5;  ///< 32 x 32 tiles per directory block

  TileMap(uint32_t width, uint32_t height)
      : tiles_x_((width + kTileSide - 1) >> kTileShift),
        tiles_y_((height + kTileSide - 1) >> kTileShift),
        dirs_x_((tiles_x_ + (1u << kDirShift) - 1) >> kDirShift),
        dirs_((size_t(dirs_x_) * ((tiles_y_ + (1u << kDirShift) - 1) >> kDirShift))) {}

  /// The tile holding pixel (x, y); nullptr if it was never touched.
  Tile* find(uint32_t x, uint32_t y) const {
    const uint32_t tx = x >> kTileShift, ty = y >> kTileShift;
    const auto& d = dirs_[size_t(ty >> kDirShift) * dirs_x_ + (tx >> kDirShift)];
    if (!d) return nullptr;
    return (*d)[slot(tx, ty)].get();
  }

  /// The tile holding pixel (x, y), created by make() on first touch.
  template <class Make>
  Tile& get(uint32_t x, uint32_t y, Make&& make) {
    const uint32_t tx = x >> kTileShift, ty = y >> kTileShift;
    if (tx == last_tx_ && ty == last_ty_) return *last_;
    auto& d = dirs_[size_t(ty >> kDirShift) * dirs_x_ + (tx >> kDirShift)];
    if (!d) d = std::make_unique<Dir>(size_t{1} << (2 * kDirShift));
    auto& t = (*d)[slot(tx, ty)];
    if (!t) {
      t = make(tx << kTileShift, ty << kTileShift);
      ++count_;
    }
    last_tx_ = tx;
    last_ty_ = ty;
    last_ = t.get();
    return *last_;
  }

  /// Calls f(tile_x0, tile_y0, tile) for every touched tile in raster order of
  /// directory blocks, then tiles.
  template <class F>
  void for_each(F&& f) const {
    for (size_t di = 0; di < dirs_.size(); ++di) {
      if (!dirs_[di]) continue;
      for (size_t s = 0; s < dirs_[di]->size(); ++s) {
        const auto& t = (*dirs_[di])[s];
        if (!t) continue;
        uint32_t tx = uint32_t(di % dirs_x_) << kDirShift | uint32_t(s & ((1u << kDirShift) - 1));
        uint32_t ty = uint32_t(di / dirs_x_) << kDirShift | uint32_t(s >> kDirShift);
        f(tx << kTileShift, ty << kTileShift, *t);
      }
    }
  }

  /// Moves every tile of o into this map, which must not hold any of them
  /// (maps over disjoint sets of tiles, e.g. one per thread); o is left empty.
  /// Returns false, moving nothing more, at the first tile both hold.
  bool absorb(TileMap& o) {
    if (o.dirs_.size() != dirs_.size()) return false;
    for (size_t di = 0; di < o.dirs_.size(); ++di) {
      if (!o.dirs_[di]) continue;
      auto& d = dirs_[di];
      if (!d) d = std::make_unique<Dir>(size_t{1} << (2 * kDirShift));
      for (size_t s = 0; s < d->size(); ++s) {
        auto& from = (*o.dirs_[di])[s];
        if (!from) continue;
        auto& to = (*d)[s];
        if (to) return false;
        to = std::move(from);
        ++count_;
        --o.count_;
      }
      o.dirs_[di].reset();
    }
    o.last_tx_ = o.last_ty_ = ~0u;
    o.last_ = nullptr;
    return true;
  }

  size_t tiles() const { return count_; }
  size_t directory_bytes() const {
    size_t n = dirs_.size() * sizeof(std::unique_ptr<Dir>);
    for (const auto& d : dirs_)
      if (d) n += sizeof(Dir) + d->size() * sizeof(std::unique_ptr<Tile>);
    return n;
  }

 private:
  using Dir = std::vector<std::unique_ptr<Tile>>;
  static size_t slot(uint32_t tx, uint32_t ty) {
    return size_t(ty & ((1u << kDirShift) - 1)) << kDirShift | (tx & ((1u << kDirShift) - 1));
  }
  uint32_t tiles_x_, tiles_y_, dirs_x_;
  std::vector<std::unique_ptr<Dir>> dirs_;
  size_t count_ = 0;
  uint32_t last_tx_ = ~0u, last_ty_ = ~0u;
  Tile* last_ = nullptr;
};

}  // namespace ropsim
