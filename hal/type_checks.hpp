// Minimal compile-time helpers for the HAL contracts. The firmware side is C++14 for avr-g++ 5.4
// and has no <type_traits>, so the few traits the contract checks need live here.
#ifndef BTSM_HAL_TYPE_CHECKS_HPP
#define BTSM_HAL_TYPE_CHECKS_HPP

namespace btsm {
namespace hal {
namespace detail {

template <bool B>
struct BoolConstant {
  static constexpr bool value = B;
};
typedef BoolConstant<true> TrueType;
typedef BoolConstant<false> FalseType;

template <class A, class B>
struct IsSame : FalseType {};
template <class A>
struct IsSame<A, A> : TrueType {};

template <class... Ts>
struct MakeVoid {
  typedef void type;
};

// Declared, never defined: only for unevaluated expressions inside decltype.
template <class T>
T& lvalue() noexcept;

}  // namespace detail
}  // namespace hal
}  // namespace btsm

// The Board lvalue inside a BTSM_HAL_REQUIRE expression.
#define BTSM_BOARD (::btsm::hal::detail::lvalue<Board>())

// BTSM_HAL_REQUIRE(name, Result, expr): defines name<Board>::value, true when `expr` (written
// with BTSM_BOARD for the board object) compiles and has exactly the type Result.
#define BTSM_HAL_REQUIRE(name, Result, expr)                                                  \
  template <class Board, class = void>                                                       \
  struct name : ::btsm::hal::detail::FalseType {};                                           \
  template <class Board>                                                                     \
  struct name<Board, typename ::btsm::hal::detail::MakeVoid<decltype(expr)>::type>           \
      : ::btsm::hal::detail::IsSame<decltype(expr), Result> {};

#endif
