#pragma once
// The AddressSanitizer + UBSan build (scripts/test.sh --asan) runs each path once, on a short
// input; the figures (accuracy over seeds, long runs, sweeps) are asserted in Release.

namespace cairn::test {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif

}  // namespace cairn::test
