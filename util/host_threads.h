// The host threads a process's golden model may use (--threads): a process
// setting, like the memory budget, set once by the CLI. Threads never change
// a result (golden_model.h); they only change how fast it comes. Bottom
// layer: the standard library only.
#pragma once

namespace ropsim {

/// The cores this process may run on (its CPU affinity), at least 1.
int available_cores();
/// The threads the golden model uses by default: --threads, or
/// available_cores() until it is set.
int host_threads();
/// Sets host_threads(); n >= 1.
void set_host_threads(int n);

}  // namespace ropsim
