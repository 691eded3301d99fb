// Lists of types (contact laws, container shapes) chosen by an enum that follows their order:
// the one way host code turns a deck's choice into the type the kernels are written for.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace pdsim {

namespace type_list_detail {
template <class List, class F, std::size_t... K>
auto with_index(std::size_t k, F& f, std::index_sequence<K...>) {
  using Result = decltype(f(std::tuple_element_t<0, List>{}));
  if constexpr (std::is_void_v<Result>) {
    ((k == K ? f(std::tuple_element_t<K, List>{}) : void()), ...);
  } else {
    Result out{};
    ((k == K ? void(out = f(std::tuple_element_t<K, List>{})) : void()), ...);
    return out;
  }
}
template <class List, class T, std::size_t K = 0>
constexpr std::size_t index_of() {
  if constexpr (std::is_same_v<T, std::tuple_element_t<K, List>>)
    return K;
  else
    return index_of<List, T, K + 1>();
}
}  // namespace type_list_detail

// f(T{}) with the type of List (a std::tuple of empty types) whose place is `choice`.
template <class List, class Enum, class F>
auto with_type(Enum choice, F&& f) {
  return type_list_detail::with_index<List>(static_cast<std::size_t>(choice), f,
                                            std::make_index_sequence<std::tuple_size_v<List>>());
}

// The enum value of type T's place in List.
template <class List, class Enum, class T>
constexpr Enum place_of = static_cast<Enum>(type_list_detail::index_of<List, T>());

// T::name of the choice, and the choice of a name (std::invalid_argument when none has it).
template <class List, class Enum>
const char* name_of(Enum choice) {
  return with_type<List>(choice, [](auto t) { return decltype(t)::name; });
}
// Every name of List, in its order (the choices a deck offers).
template <class List>
std::vector<std::string_view> names_of() {
  return std::apply([](auto... t) { return std::vector<std::string_view>{decltype(t)::name...}; },
                    List{});
}
template <class List, class Enum>
Enum named(const std::string& name) {
  for (std::size_t k = 0; k < std::tuple_size_v<List>; ++k)
    if (name == name_of<List>(static_cast<Enum>(k))) return static_cast<Enum>(k);
  throw std::invalid_argument("no choice named '" + name + "'");
}

}  // namespace pdsim
