// The four fidelities a run can take, from the fastest estimate to the full
// cycle model (docs/results.md "The speed/accuracy trade"): their names as
// the CLI and study files spell them, and what each gives.
#pragma once
#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace ropsim {

enum class Fidelity {
  kFunctional,   ///< the golden model: image, counters, state; no time
  kCycle,        ///< the cycle-approximate SystemC pipeline
  kSampled,      ///< the pipeline on sampling units from live-points, with 95 % intervals
  kApproximate,  ///< the analytical model over tag-only caches and DRAM
};

inline constexpr std::array<Fidelity, 4> kFidelities = {Fidelity::kFunctional, Fidelity::kCycle, Fidelity::kSampled,
                                                        Fidelity::kApproximate};

inline const char* to_string(Fidelity f) {
  switch (f) {
    case Fidelity::kFunctional:
      return "functional";
    case Fidelity::kCycle:
      return "cycle";
    case Fidelity::kSampled:
      return "sampled";
    case Fidelity::kApproximate:
      return "approximate";
  }
  return "?";
}

/// The fidelity a name spells, or none.
inline std::optional<Fidelity> parse_fidelity(std::string_view name) {
  for (Fidelity f : kFidelities)
    if (name == to_string(f)) return f;
  return std::nullopt;
}

/// Every fidelity's name, in order.
inline std::vector<std::string> fidelity_names() {
  std::vector<std::string> v;
  for (Fidelity f : kFidelities) v.emplace_back(to_string(f));
  return v;
}

/// Does the fidelity give time (and so take a design)?
inline bool is_timed(Fidelity f) { return f != Fidelity::kFunctional; }

}  // namespace ropsim
