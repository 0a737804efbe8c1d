# cmake -DFROM=DIR -DTO=DIR -DFILES=a_pb2.py,b_pb2.py -P fix_imports.cmake
#
# Copies the Python modules protoc generated for proto/*.proto from FROM to
# TO (the package locus.proto), making their imports of each other
# relative: `from proto import scene_pb2 as ...` becomes
# `from . import scene_pb2 as ...`. Fails when a generated file is missing
# or an absolute import of `proto` is left (a protoc whose output looks
# different), so a broken package never reaches the build tree.
if(NOT FROM OR NOT TO OR NOT FILES)
  message(FATAL_ERROR "usage: cmake -DFROM=DIR -DTO=DIR -DFILES=a.py,b.py -P fix_imports.cmake")
endif()
string(REPLACE "," ";" files "${FILES}")
foreach(name ${files})
  if(NOT EXISTS ${FROM}/${name})
    message(FATAL_ERROR "fix_imports: protoc did not write ${FROM}/${name}")
  endif()
  file(READ ${FROM}/${name} text)
  string(REGEX REPLACE "(^|\n)from proto import " "\\1from . import " text "${text}")
  if(text MATCHES "(^|\n)[ \t]*(from|import)[ \t]+proto([ \t.]|\n)")
    message(FATAL_ERROR
      "fix_imports: ${FROM}/${name} still imports the top-level package `proto` "
      "(a generated import this script does not know how to make relative)")
  endif()
  file(WRITE ${TO}/${name}.tmp "${text}")
  file(RENAME ${TO}/${name}.tmp ${TO}/${name})
endforeach()
