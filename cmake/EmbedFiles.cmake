# umbra_embed_files(<output.cpp> <namespace-function> <base-dir> <files...>)
#
# Generates a C++ source that defines
#   std::string_view <function>(std::string_view relative_path)
# returning the bytes of each embedded file (empty view when unknown), plus
#   const std::vector<std::string_view>& <function>_names()
# The files are read at build time, so editing a shader or a web file rebuilds
# only this source and the binary carries its assets with it (runs from anywhere).
function(umbra_embed_files output function base_dir)
  set(files ${ARGN})
  set(abs_files "")
  foreach(f IN LISTS files)
    list(APPEND abs_files "${base_dir}/${f}")
  endforeach()
  add_custom_command(
    OUTPUT "${output}"
    COMMAND "${CMAKE_COMMAND}"
      "-DOUTPUT=${output}" "-DFUNCTION=${function}" "-DBASE_DIR=${base_dir}"
      "-DFILES=${files}"
      -P "${PROJECT_SOURCE_DIR}/cmake/embed_files_script.cmake"
    DEPENDS ${abs_files} "${PROJECT_SOURCE_DIR}/cmake/embed_files_script.cmake"
    COMMENT "Embedding ${function}: ${files}"
    VERBATIM)
endfunction()
