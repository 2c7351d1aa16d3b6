# gimforge_warnings: an INTERFACE target every project target links privately.
add_library(gimforge_warnings INTERFACE)
target_compile_options(gimforge_warnings INTERFACE
  $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wsign-conversion
    -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Wunused -Woverloaded-virtual -Wnull-dereference
    -Wdouble-promotion -Wformat=2 -Wimplicit-fallthrough>)
if(GIMFORGE_WERROR)
  target_compile_options(gimforge_warnings INTERFACE $<$<COMPILE_LANGUAGE:CXX>:-Werror>)
endif()
