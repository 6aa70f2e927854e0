# cairn_enable_sanitizers("address,undefined" SCOPE [SKIP]): -fsanitize flags.
#   SCOPE all        every target is instrumented (needed for thread: TSan must see every
#                    access);
#   SCOPE libraries  only the cairn libraries (cairn_add_library) are instrumented, the
#                    programs (apps, tests, benchmarks) are linked with the runtimes but not
#                    instrumented themselves. Inline code of the libraries' headers compiled
#                    into a program is not checked.
#   SCOPE a;b;c      only the named library targets (e.g. cairn_od;cairn_od_io;cairn_map;
#                    cairn_sources;cairn_sources_mrpt: the code that reads and processes
#                    input).
#   SKIP             checks of -fsanitize=undefined left out, e.g. "alignment,null": they
#                    double the compile time of Eigen-heavy code under GCC; a null
#                    dereference still stops the run as an ASan SEGV report, and unaligned
#                    scalar loads are defined behaviour on x86-64.
function(cairn_enable_sanitizers list scope)
  set(skip "${ARGV2}")
  if(list STREQUAL "")
    return()
  endif()
  string(REPLACE "," ";" sanitizers "${list}")
  foreach(s IN LISTS sanitizers)
    if(NOT s MATCHES "^(address|undefined|thread|leak)$")
      message(FATAL_ERROR "CAIRN_SANITIZE: unknown sanitizer '${s}' (address, undefined, thread, leak)")
    endif()
  endforeach()
  if(NOT scope STREQUAL "all" AND "thread" IN_LIST sanitizers)
    message(FATAL_ERROR "CAIRN_SANITIZE_SCOPE=${scope} does not work with thread (TSan must see every access)")
  endif()
  if("address" IN_LIST sanitizers)
    # Under ASan Eigen stops trusting malloc's 16-byte alignment (__SANITIZE_ADDRESS__) and
    # allocates with an offset header, while Debian's libceres.a, built without ASan, frees
    # Eigen's buffers with plain free(): a "bad-free" in ceres::Covariance. One allocation
    # scheme everywhere: ASan's allocator returns 16-byte aligned blocks on x86-64 as glibc
    # does, which is what Eigen's default assumes.
    add_compile_definitions(EIGEN_MALLOC_ALREADY_ALIGNED=1)
  endif()
  string(REPLACE ";" "," flags "${sanitizers}")
  set(compile -fsanitize=${flags} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  if(NOT skip STREQUAL "")
    if(NOT "undefined" IN_LIST sanitizers)
      message(FATAL_ERROR "CAIRN_SANITIZE_SKIP=${skip} needs undefined in CAIRN_SANITIZE")
    endif()
    string(REPLACE "," ";" skipped "${skip}")
    foreach(s IN LISTS skipped)
      if(NOT s MATCHES "^[a-z-]+$")
        message(FATAL_ERROR "CAIRN_SANITIZE_SKIP: '${s}' is not a UBSan check name")
      endif()
    endforeach()
    list(APPEND compile -fno-sanitize=${skip})
  endif()
  if(scope STREQUAL "all")
    add_compile_options(${compile})
  else()
    set_property(GLOBAL PROPERTY CAIRN_LIBRARY_SANITIZE_OPTIONS "${compile}")
    set_property(GLOBAL PROPERTY CAIRN_LIBRARY_SANITIZE_TARGETS "${scope}")
  endif()
  add_link_options(-fsanitize=${flags})
endfunction()
