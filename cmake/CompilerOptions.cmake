# Warnings for one target, applied target by target rather than globally.
function(cairn_set_warnings target)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow
                                             -Wnon-virtual-dtor -Wcast-align -Wunused
                                             -Woverloaded-virtual)
  endif()
endfunction()
