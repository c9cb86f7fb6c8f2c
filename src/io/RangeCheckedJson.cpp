#include "io/RangeCheckedJson.hpp"

#include <fmt/format.h>

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "config/ParameterSet.hpp"

namespace ehlsim {

namespace {

/// The DOM builder json::parse uses (nlohmann's json_sax_dom_parser), with
/// the path of the value being read and a check of each number's text, which
/// only the SAX interface shows.
class RangeCheckingSax final : public nlohmann::json_sax<nlohmann::json> {
 public:
  RangeCheckingSax(nlohmann::json& result, std::string name)
      : dom_(result), name_(std::move(name)) {}

  bool null() override { return value_done(dom_.null()); }
  bool boolean(bool v) override { return value_done(dom_.boolean(v)); }
  bool number_integer(number_integer_t v) override { return value_done(dom_.number_integer(v)); }
  bool number_unsigned(number_unsigned_t v) override { return value_done(dom_.number_unsigned(v)); }
  bool number_float(number_float_t v, const string_t& text) override {
    if (underflowed_to_zero(v, text)) fail(text, double_underflow_reason());
    return value_done(dom_.number_float(v, text));
  }
  bool string(string_t& v) override { return value_done(dom_.string(v)); }
  bool binary(binary_t& v) override { return value_done(dom_.binary(v)); }
  bool start_object(std::size_t n) override { return open(dom_.start_object(n), false); }
  bool key(string_t& k) override {
    path_.back().key = k;
    return dom_.key(k);
  }
  bool end_object() override { return close(dom_.end_object()); }
  bool start_array(std::size_t n) override { return open(dom_.start_array(n), true); }
  bool end_array() override { return close(dom_.end_array()); }
  bool parse_error(std::size_t, const std::string& token,
                   const nlohmann::detail::exception& e) override {
    // 406: a number beyond the range of a double (nlohmann::json's id).
    constexpr int kNumberOverflow = 406;
    if (e.id == kNumberOverflow) fail(token, double_overflow_reason());
    throw ConfigError(fmt::format("cannot read '{}': {}", name_, e.what()));
  }

 private:
  struct Level {
    bool array = false;
    std::string key;
    std::size_t index = 0;
  };

  bool open(bool ok, bool array) {
    path_.push_back({array, {}, 0});
    return ok;
  }
  bool close(bool ok) {
    path_.pop_back();
    return value_done(ok);
  }
  /// The next element of an array is the next index.
  bool value_done(bool ok) {
    if (!path_.empty() && path_.back().array) ++path_.back().index;
    return ok;
  }
  [[noreturn]] void fail(const std::string& literal, const std::string& reason) const {
    std::string where;
    for (const Level& level : path_) {
      if (level.array) {
        where += fmt::format("[{}]", level.index);
        continue;
      }
      if (!where.empty()) where += '.';
      where += echo_input(level.key);
    }
    throw ConfigError(fmt::format("cannot read '{}': {} = {} {}", name_,
                                  where.empty() ? "the value" : where, echo_input(literal),
                                  reason));
  }

  nlohmann::detail::json_sax_dom_parser<nlohmann::json> dom_;
  std::string name_;
  std::vector<Level> path_;
};

}  // namespace

nlohmann::json parse_range_checked_json(std::istream& in, const std::string& name) {
  nlohmann::json result;
  RangeCheckingSax sax(result, name);
  (void)nlohmann::json::sax_parse(in, &sax);
  return result;
}

}  // namespace ehlsim
