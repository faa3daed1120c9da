# Writes OUT, a C++ header holding the text of IN as the string constant NAME
# (a raw string literal), and rewrites it only when that text changed, so that
# an edit of IN rebuilds what includes OUT and nothing else.
#   cmake -DIN=file.csv -DOUT=header.h -DNAME=kConstant -P embed_csv.cmake
file(READ "${IN}" text)
set(content "// Generated from ${IN} by cmake/embed_csv.cmake: do not edit.\n#pragma once\n"
  "namespace ropsim {\ninline constexpr const char* ${NAME} = R\"csv(${text})csv\";\n}\n")
set(old "")
if(EXISTS "${OUT}")
  file(READ "${OUT}" old)
endif()
if(NOT old STREQUAL content)
  file(WRITE "${OUT}" "${content}")
endif()
