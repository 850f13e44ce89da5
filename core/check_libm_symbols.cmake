# Fails when the tracing library calls a C library function whose result may depend on the CPU (glibc picks FMA or
# plain variants of sinf, cosf, expf, exp, ... at run time) or on the library's release: the renderer computes those
# itself (core/util/trig.h, core/util/exp_log.h) so that pixels never depend on the machine. Two callers are allowed because
# their results are not pixels: the sRGB curve of the PNG preview (image.cpp) and the generated test meshes of
# mesh.cpp (used by tests and benchmarks, never by a scene). sqrt, floor, ldexp and frexp are exact and allowed.
# Run by ctest as CoreLibmSymbols: cmake -DNM=nm -DARCHIVE=libtessera_core.a -P this file.
if(NOT NM OR NOT ARCHIVE)
  message(FATAL_ERROR "usage: cmake -DNM=<nm> -DARCHIVE=<libtessera_core.a> -P check_libm_symbols.cmake")
endif()
execute_process(COMMAND ${NM} -u -A ${ARCHIVE} OUTPUT_VARIABLE out RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${NM} failed on ${ARCHIVE}")
endif()
set(functions sin cos tan sincos asin acos atan atan2 sinh cosh tanh asinh acosh atanh exp exp2 exp10 expm1 log log2
  log10 log1p pow cbrt hypot erf erfc tgamma lgamma)
set(allowed "image\\.cpp\\.o:powf" "mesh\\.cpp\\.o:(sin|cos|sincos)")
string(REPLACE "\n" ";" lines "${out}")
set(bad "")
set(seen 0)
foreach(line IN LISTS lines)
  # "<archive>:<member>:  U <name>[@version]"
  if(line MATCHES "^[^:]*:([^:]*):[ \t]*U ([A-Za-z0-9_]+)")
    set(member "${CMAKE_MATCH_1}")
    set(name "${CMAKE_MATCH_2}")
    math(EXPR seen "${seen} + 1")
    foreach(f IN LISTS functions)
      if(name MATCHES "^(__)?${f}(f|l)?(_finite)?$")
        set(ok FALSE)
        foreach(a IN LISTS allowed)
          if("${member}:${name}" MATCHES "^${a}$")
            set(ok TRUE)
          endif()
        endforeach()
        if(NOT ok)
          string(APPEND bad "  ${member}: ${name}\n")
        endif()
      endif()
    endforeach()
  endif()
endforeach()
if(seen EQUAL 0)
  message(FATAL_ERROR "no undefined symbols read from ${ARCHIVE}: is it the library?")
endif()
if(bad)
  message(FATAL_ERROR "the tracing library calls C library functions whose results may differ between machines:\n${bad}"
    "use portable_* from core/util/trig.h or core/util/exp_log.h")
endif()
message(STATUS "${seen} undefined symbols read, none of them a machine-dependent math function")
