# SPDX-License-Identifier: Apache-2.0
# Installs the psq build into a scratch prefix, then configures, builds and
# runs tests/consumer against it with find_package(psq).
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
if(NOT BUILD_TYPE)
  set(BUILD_TYPE Release)
endif()
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
endfunction()
run(${CMAKE_COMMAND} --install "${PSQ_BUILD_DIR}" --prefix "${WORK_DIR}/prefix" --config ${BUILD_TYPE})
run(${CMAKE_COMMAND} -S "${CONSUMER_SOURCE}" -B "${WORK_DIR}/build"
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix -DCMAKE_BUILD_TYPE=${BUILD_TYPE}
    -DCMAKE_CXX_FLAGS=${CONSUMER_CXX_FLAGS})
run(${CMAKE_COMMAND} --build "${WORK_DIR}/build")
run("${WORK_DIR}/build/consumer" "${WORK_DIR}/triangle.ply")
message(STATUS "consumer built against the installed psq and ran")

# An application of the codec alone: find_package(psq COMPONENTS codec),
# with libdraco made unfindable, as on a machine without libdraco-dev.
run(${CMAKE_COMMAND} -S "${CONSUMER_SOURCE}/codec_only" -B "${WORK_DIR}/build_codec"
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix -DCMAKE_DISABLE_FIND_PACKAGE_draco=ON -DCMAKE_BUILD_TYPE=${BUILD_TYPE}
    -DCMAKE_CXX_FLAGS=${CONSUMER_CXX_FLAGS})
run(${CMAKE_COMMAND} --build "${WORK_DIR}/build_codec")
run("${WORK_DIR}/build_codec/codec_consumer")
message(STATUS "codec-only consumer built with COMPONENTS codec and ran")
