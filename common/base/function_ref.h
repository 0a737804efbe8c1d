// A non-owning reference to a callable, for a callback that crosses into
// another translation unit without a template or std::function's copy (in
// short, what C++26 calls std::function_ref). The callable must outlive the
// reference: pass one as a parameter, do not store it.
#pragma once

#include <memory>
#include <type_traits>
#include <utility>

namespace locus {

template <class Signature>
class FunctionRef;

template <class R, class... Args>
class FunctionRef<R(Args...)> {
 public:
  // Any callable but a FunctionRef itself (that one is copied).
  template <class F,
            class = std::enable_if_t<!std::is_same_v<std::remove_cvref_t<F>, FunctionRef> &&
                                     std::is_invocable_r_v<R, F&, Args...>>>
  FunctionRef(F&& f)  // NOLINT(google-explicit-constructor): binds like a function parameter
      : callable_(const_cast<void*>(static_cast<const void*>(std::addressof(f)))),
        call_([](void* callable, Args... args) -> R {
          return (*static_cast<std::remove_reference_t<F>*>(callable))(std::forward<Args>(args)...);
        }) {}

  R operator()(Args... args) const { return call_(callable_, std::forward<Args>(args)...); }

 private:
  void* callable_;
  R (*call_)(void*, Args...);
};

}  // namespace locus
