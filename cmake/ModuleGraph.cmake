# The module graph (DESIGN.md "Layout") checked at configure time:
# core ← synth ← learn. synth must not reach Ceres, libtorch or cairo, directly
# or through another target, and no module library may link avsi_learn (only
# the CLI's training commands and the benchmarks need it). A violation stops
# the configuration with the path that links the forbidden library.

# Sets out_var to the transitive link items of `target` (targets and plain
# library names or paths), each as "item<TAB>path from target".
function(avsi_link_closure target out_var)
  set(result "")
  set(seen "")
  set(queue "${target}")
  set(path_${target} "${target}")
  while(queue)
    list(POP_FRONT queue current)
    if(current IN_LIST seen)
      continue()
    endif()
    list(APPEND seen "${current}")
    set(items "")
    if(TARGET ${current})
      get_target_property(type ${current} TYPE)
      if(NOT type STREQUAL "INTERFACE_LIBRARY")
        get_target_property(direct ${current} LINK_LIBRARIES)
        if(direct)
          list(APPEND items ${direct})
        endif()
      endif()
      get_target_property(iface ${current} INTERFACE_LINK_LIBRARIES)
      if(iface)
        list(APPEND items ${iface})
      endif()
    endif()
    foreach(item IN LISTS items)
      # $<LINK_ONLY:x> (a static library's private dependency) links x too.
      string(REGEX REPLACE "^\\$<LINK_ONLY:(.*)>$" "\\1" item "${item}")
      if(item MATCHES "^\\$<" OR item STREQUAL "")
        continue()
      endif()
      string(MAKE_C_IDENTIFIER "${item}" key)
      if(NOT DEFINED path_${key})
        string(MAKE_C_IDENTIFIER "${current}" ckey)
        if(DEFINED path_${ckey})
          set(path_${key} "${path_${ckey}} -> ${item}")
        else()
          set(path_${key} "${target} -> ${item}")
        endif()
        list(APPEND result "${item}\t${path_${key}}")
      endif()
      list(APPEND queue "${item}")
    endforeach()
  endwhile()
  set(${out_var} "${result}" PARENT_SCOPE)
endfunction()

# Fails the configuration if `target` links anything matching one of the
# regular expressions in FORBIDDEN (matched against target names and library
# file names).
function(avsi_forbid_links target)
  cmake_parse_arguments(F "" "REASON" "FORBIDDEN" ${ARGN})
  if(NOT TARGET ${target})
    return()
  endif()
  avsi_link_closure(${target} closure)
  foreach(entry IN LISTS closure)
    string(REPLACE "\t" ";" parts "${entry}")
    list(GET parts 0 item)
    list(GET parts 1 path)
    get_filename_component(name "${item}" NAME)
    foreach(pattern IN LISTS F_FORBIDDEN)
      if(item MATCHES "${pattern}" OR name MATCHES "${pattern}")
        message(FATAL_ERROR "module graph: ${target} links ${item} (${path}); ${F_REASON}")
      endif()
    endforeach()
  endforeach()
endfunction()

# The checks of DESIGN.md's module table.
function(avsi_check_module_graph)
  foreach(module core synth vocoder stimuli experiment analysis)
    avsi_forbid_links(avsi_${module}
      FORBIDDEN "^avsi_learn$"
      REASON "only the CLI's training commands and the benchmarks may link avsi_learn")
  endforeach()
  avsi_forbid_links(avsi_synth
    FORBIDDEN "^Ceres::" "^ceres$" "libceres" "^torch" "libtorch" "^c10$" "libc10" "CAIRO" "^cairo$" "libcairo"
    REASON "synth holds the models only and must stay free of Ceres, libtorch and cairo (they belong in learn/)")
endfunction()
