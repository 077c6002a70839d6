// Batch calls into the C++ API of the libsumo that CPython has loaded (syncroad, direct.rs).
//
// libsumo's Python module is a SWIG wrapper around the static functions of libsumo::Vehicle
// and libsumo::Simulation;
// its shared object exports them. Calling them through these shims skips one interpreter
// round trip per vehicle and step, on the same simulation the Python module started.
// Every exception stops the batch and is reported with the index of the vehicle.

#include <cstddef>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace {
using GetF64 = double (*)(const std::string&);
using SetF64 = void (*)(const std::string&, double);
using GetInt = int (*)();
using GetLeader = std::pair<std::string, double> (*)(const std::string&, double);

void copy_message(const char* what, char* err, std::size_t errlen) {
    if (err == nullptr || errlen == 0) {
        return;
    }
    std::strncpy(err, what, errlen - 1);
    err[errlen - 1] = '\0';
}
// call(i) for i = 0 .. n-1; returns 0, or 1 + the index of the call that threw, its message
// in `err`.
template <typename F>
std::size_t each(std::size_t n, char* err, std::size_t errlen, F call) {
    std::size_t i = 0;
    try {
        for (; i < n; ++i) {
            call(i);
        }
    } catch (const std::exception& e) {
        copy_message(e.what(), err, errlen);
        return i + 1;
    } catch (...) {
        copy_message("unknown C++ exception", err, errlen);
        return i + 1;
    }
    return 0;
}
}  // namespace

struct sr_ids {
    std::vector<std::string> ids;
};

extern "C" {

sr_ids* sr_ids_new(const char* const* ids, const std::size_t* lens, std::size_t n) {
    try {
        auto* v = new sr_ids;
        v->ids.reserve(n);
        for (std::size_t i = 0; i < n; ++i) {
            v->ids.emplace_back(ids[i], lens[i]);
        }
        return v;
    } catch (...) {
        return nullptr;
    }
}

void sr_ids_free(sr_ids* ids) { delete ids; }

// out[i] = fn(ids[i]); returns 0, or 1 + the index of the vehicle whose call threw.
std::size_t sr_get_f64(void* fn, const sr_ids* ids, double* out, char* err, std::size_t errlen) {
    auto f = reinterpret_cast<GetF64>(fn);
    return each(ids->ids.size(), err, errlen, [&](std::size_t i) { out[i] = f(ids->ids[i]); });
}

// out[k] = fns[k]() for n counts of the simulation; returns 0, or 1 + the index of the call
// that threw.
std::size_t sr_get_ints(void* const* fns, int* out, std::size_t n, char* err, std::size_t errlen) {
    return each(n, err, errlen, [&](std::size_t k) { out[k] = reinterpret_cast<GetInt>(fns[k])(); });
}

// fn(ids[i], in[i]) for every vehicle; returns 0, or 1 + the index of the call that threw.
std::size_t sr_set_f64(void* fn, const sr_ids* ids, const double* in, char* err, std::size_t errlen) {
    auto f = reinterpret_cast<SetF64>(fn);
    return each(ids->ids.size(), err, errlen, [&](std::size_t i) { f(ids->ids[i], in[i]); });
}

// For every vehicle, whoever SUMO reports ahead of it within `dist` (getLeader) and, where that
// is a vehicle (a non-empty id at a gap >= 0), its speed (getSpeed of that id) and the gap; NaN
// for both where nobody is. Returns 0, or 1 + the index of the vehicle whose call threw.
std::size_t sr_leaders(void* leader_fn, void* speed_fn, const sr_ids* ids, double dist,
                       double* speed, double* gap, char* err, std::size_t errlen) {
    auto leader = reinterpret_cast<GetLeader>(leader_fn);
    auto get_speed = reinterpret_cast<GetF64>(speed_fn);
    return each(ids->ids.size(), err, errlen, [&](std::size_t i) {
        const std::pair<std::string, double> l = leader(ids->ids[i], dist);
        if (!l.first.empty() && l.second >= 0.0) {
            speed[i] = get_speed(l.first);
            gap[i] = l.second;
        } else {
            speed[i] = std::numeric_limits<double>::quiet_NaN();
            gap[i] = std::numeric_limits<double>::quiet_NaN();
        }
    });
}

// For the shims' own tests: throws as libsumo does for an unknown vehicle.
int sr_test_throw() { throw std::runtime_error("Vehicle 'ghost' is not known"); }
}
