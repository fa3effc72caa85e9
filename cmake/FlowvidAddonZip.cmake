# Builds the Blender add-on zip (cmake -P): one archive that Blender 3.x/4.x's
# "Install..." (bl_info) and 4.2+'s extension installer (blender_manifest.toml)
# both accept: everything under a top folder flowvid_blender/.
#
#   -DSOURCE=<repo>/blender_addon/flowvid_blender  -DOUTPUT=<zip>  -DSTAGE=<scratch folder>
#   -DVERSION=<project version>          checked against the manifest and bl_info
#   -DMODULE=<flowvid*.so>               optional: carried in native/ (used when it imports in Blender's Python)
#   -DRECORD_TOOL=<path> -DRECORD_MODULE_DIR=<path>
#                                        optional: written to locations.json, where the add-on looks
#                                        when the preferences and environment name nothing
foreach(required SOURCE OUTPUT STAGE VERSION)
  if(NOT ${required})
    message(FATAL_ERROR "FlowvidAddonZip.cmake: -D${required}=... is required")
  endif()
endforeach()

# One version everywhere: a zip whose manifest says another would install as another release.
file(STRINGS "${SOURCE}/blender_manifest.toml" manifest_version REGEX "^version *=")
string(REGEX REPLACE "^version *= *\"([^\"]*)\".*" "\\1" manifest_version "${manifest_version}")
file(STRINGS "${SOURCE}/__init__.py" bl_info_version REGEX "\"version\": *\\(")
string(REGEX REPLACE ".*\\(([0-9]+), *([0-9]+), *([0-9]+)\\).*" "\\1.\\2.\\3" bl_info_version "${bl_info_version}")
if(NOT manifest_version STREQUAL VERSION OR NOT bl_info_version STREQUAL VERSION)
  message(FATAL_ERROR "flowvid add-on: blender_manifest.toml says ${manifest_version}, bl_info says "
                      "${bl_info_version}, the project is ${VERSION}: make them equal")
endif()

file(REMOVE_RECURSE "${STAGE}")
file(MAKE_DIRECTORY "${STAGE}")
file(COPY "${SOURCE}" DESTINATION "${STAGE}" PATTERN "__pycache__" EXCLUDE PATTERN "*.pyc" EXCLUDE)
if(MODULE)
  file(COPY "${MODULE}" DESTINATION "${STAGE}/flowvid_blender/native")
endif()
if(RECORD_TOOL OR RECORD_MODULE_DIR)
  file(WRITE "${STAGE}/flowvid_blender/locations.json"
       "{\"tool\": \"${RECORD_TOOL}\", \"module_dir\": \"${RECORD_MODULE_DIR}\"}\n")
endif()

get_filename_component(output_dir "${OUTPUT}" DIRECTORY)
file(MAKE_DIRECTORY "${output_dir}")
file(REMOVE "${OUTPUT}")
execute_process(COMMAND "${CMAKE_COMMAND}" -E tar cf "${OUTPUT}" --format=zip flowvid_blender
                WORKING_DIRECTORY "${STAGE}" RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "flowvid add-on: could not write ${OUTPUT}")
endif()
