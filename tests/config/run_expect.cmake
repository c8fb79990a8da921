# cmake -DCMD="a;b;c" -DEXPECT_RC=N -DEXPECT_OUT=regex -P run_expect.cmake
# Runs CMD, fails unless its exit code is EXPECT_RC and stdout+stderr match EXPECT_OUT.
execute_process(COMMAND ${CMD} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL EXPECT_RC)
  message(FATAL_ERROR "exit code ${rc}, expected ${EXPECT_RC}\nstdout:\n${out}\nstderr:\n${err}")
endif()
if(DEFINED EXPECT_OUT AND NOT "${out}${err}" MATCHES "${EXPECT_OUT}")
  message(FATAL_ERROR "output does not match '${EXPECT_OUT}'\nstdout:\n${out}\nstderr:\n${err}")
endif()
