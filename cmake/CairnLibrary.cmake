# cairn_add_library(<target> EXPORT_NAME <name> [NO_INSTALL] SOURCES <src>...)
#
# One cairn library: target <target> with alias cairn::<name>, public headers in
# ${CMAKE_CURRENT_SOURCE_DIR}/include, C++17, the project's warnings, installed and exported
# into cairn-targets (unless NO_INSTALL). Link dependencies are added by the caller.
function(cairn_add_library target)
  cmake_parse_arguments(ARG "NO_INSTALL" "EXPORT_NAME" "SOURCES" ${ARGN})
  add_library(${target} ${ARG_SOURCES})
  add_library(cairn::${ARG_EXPORT_NAME} ALIAS ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${ARG_EXPORT_NAME} OUTPUT_NAME ${target})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_compile_features(${target} PUBLIC cxx_std_17)
  cairn_set_warnings(${target})
  get_property(sanitize GLOBAL PROPERTY CAIRN_LIBRARY_SANITIZE_OPTIONS)
  get_property(sanitize_targets GLOBAL PROPERTY CAIRN_LIBRARY_SANITIZE_TARGETS)
  if(sanitize AND (sanitize_targets STREQUAL "libraries" OR target IN_LIST sanitize_targets))
    target_compile_options(${target} PRIVATE ${sanitize})  # CAIRN_SANITIZE_SCOPE
  endif()
  if(ARG_NO_INSTALL)
    return()
  endif()
  install(TARGETS ${target} EXPORT cairn-targets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endfunction()
