#pragma once
// Debian's cpp-httplib (libcpp-httplib-dev), included through here. httplib.h includes
// <resolv.h>, whose `_res` macro (the resolver's state) breaks any later header that uses `_res`
// as a name (Eigen's products do); nothing here uses the resolver's state, so the macro goes.
#include <httplib.h>

#ifdef _res
#undef _res
#endif
