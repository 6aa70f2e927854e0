# cairn_enable_sanitizers("address,undefined" SCOPE): -fsanitize flags.
#   SCOPE all        every target is instrumented (needed for thread: TSan must see every
#                    access);
#   SCOPE libraries  only the cairn libraries (cairn_add_library) are instrumented, the
#                    programs (apps, tests, benchmarks) are linked with the runtimes but not
#                    instrumented themselves: the code that reads and processes input is
#                    checked at about half the build time. Inline code of the libraries'
#                    headers compiled into a program is not checked.
function(cairn_enable_sanitizers list scope)
  if(list STREQUAL "")
    return()
  endif()
  string(REPLACE "," ";" sanitizers "${list}")
  foreach(s IN LISTS sanitizers)
    if(NOT s MATCHES "^(address|undefined|thread|leak)$")
      message(FATAL_ERROR "CAIRN_SANITIZE: unknown sanitizer '${s}' (address, undefined, thread, leak)")
    endif()
  endforeach()
  if(NOT scope MATCHES "^(all|libraries)$")
    message(FATAL_ERROR "CAIRN_SANITIZE_SCOPE: '${scope}' (expected all or libraries)")
  endif()
  if(scope STREQUAL "libraries" AND "thread" IN_LIST sanitizers)
    message(FATAL_ERROR "CAIRN_SANITIZE_SCOPE=libraries does not work with thread")
  endif()
  string(REPLACE ";" "," flags "${sanitizers}")
  set(compile -fsanitize=${flags} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  if(scope STREQUAL "all")
    add_compile_options(${compile})
  else()
    set_property(GLOBAL PROPERTY CAIRN_LIBRARY_SANITIZE_OPTIONS "${compile}")
  endif()
  add_link_options(-fsanitize=${flags})
endfunction()
