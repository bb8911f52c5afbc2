// config/key_check.h — every key-level error of a table at once, from its declared keys
// (config/keys.h), before any reader runs: `ncosim check` reports them all (issue 40 part 4).
//
// A key-level error is one that the key's own value shows, read alone: an unknown key (with a
// did-you-mean among the declared ones), a value of the wrong type, a number out of its declared
// range, a string not among its values, an array with the wrong number of entries, a required
// key missing. Each is found by the KeyReader getter the kind's reader uses, so its message is the
// reader's own. What needs more than one key (a matrix's size against the plant, a pmf's sum, a
// name that must exist elsewhere) is the reader's to check, later.
#pragma once

#include <string>
#include <vector>

#include "config/config.h"
#include "config/keys.h"

namespace ncosim::config {

struct KeyCheckOptions {
  // Key paths ("estimator[0].history") whose value another source sets (a [[sweep]]): a required
  // one is not missing, and an error at one ends with `note`.
  std::vector<std::string> set_elsewhere;
  std::string note;
};

// Whether key path `a` is `b` or lies inside it ("link[0].loss" in "link[0]").
bool path_inside(const std::string& a, const std::string& b);

// Appends the error of key `k` of `t` (read through `r`, whose keys declare it) to `errors`, if
// any; a table key with fields is checked within (its sub-tables closed).
void check_key(const Table& t, const KeyReader& r, const Key& k, const KeyCheckOptions& options,
               std::vector<LineError>& errors);

// Appends every key-level error of `t` against `keys` to `errors`: each declared key (check_key)
// and, when `closed`, every key that `keys` does not declare.
void check_table(const Table& t, const Keys& keys, bool closed, const KeyCheckOptions& options,
                 std::vector<LineError>& errors);

}  // namespace ncosim::config
