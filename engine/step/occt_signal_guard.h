// While a guard lives, a crash inside OpenCASCADE (a null entity dereferenced while translating a damaged
// file, a signal in the mesher) becomes an OCCT exception at the nearest OCC_CATCH_SIGNALS (OCCT's own
// per-entity transfer, or this module's try blocks) instead of killing the process: OCCT's handlers for
// SIGSEGV, SIGBUS, SIGFPE, SIGILL and SIGSYS (OSD::SetSignal, floating-point traps off) are installed by
// the first guard and the previous handlers put back by the last. SIGINT, SIGHUP and SIGQUIT keep the
// program's handlers. A fault outside any OCC_CATCH_SIGNALS while a guard lives (in any thread) ends the
// process with exit status 1 and OCCT's "*** Abort ***" line instead of the signal.
// Thread-safety: guards may be made and destroyed from any thread; the handlers are process-wide.
#pragma once

namespace mktree {

class OcctSignalGuard {
 public:
  OcctSignalGuard();
  ~OcctSignalGuard();
  OcctSignalGuard(const OcctSignalGuard&) = delete;
  OcctSignalGuard& operator=(const OcctSignalGuard&) = delete;
};

}  // namespace mktree
