// A fresh SystemC kernel: SystemC elaborates once per simulation context, so
// every run (and every model test) installs its own and deletes it after.
// Modules must be destroyed before the context.
#pragma once
#include <cstdlib>
#include <systemc>

namespace ropsim {

class FreshSimContext {
 public:
  FreshSimContext() {
    setenv("SYSTEMC_DISABLE_COPYRIGHT_MESSAGE", "1", 1);
    ctx_ = new sc_core::sc_simcontext;
    sc_core::sc_curr_simcontext = ctx_;
    sc_core::sc_default_global_context = ctx_;
    sc_core::sc_report_handler::set_actions(sc_core::SC_INFO, sc_core::SC_DO_NOTHING);
  }
  ~FreshSimContext() {
    delete ctx_;
    sc_core::sc_curr_simcontext = nullptr;
    sc_core::sc_default_global_context = nullptr;
  }
  FreshSimContext(const FreshSimContext&) = delete;
  FreshSimContext& operator=(const FreshSimContext&) = delete;

 private:
  sc_core::sc_simcontext* ctx_;
};

}  // namespace ropsim
