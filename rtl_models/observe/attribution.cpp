#include "rtl_models/observe/attribution.h"

namespace ropsim {

void Attribution::dram(uint32_t draw, bool write, Buffer b, uint64_t bytes) {
  if (!per_draw_) return;
  if (!last_ || last_draw_ != draw) {
    last_ = &by_draw_[draw];  // std::map: references stay valid
    last_draw_ = draw;
  }
  (write ? last_->written : last_->read)[size_t(b)] += bytes;
}

}  // namespace ropsim
