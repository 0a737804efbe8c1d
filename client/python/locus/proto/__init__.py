"""The generated stubs of proto/scene.proto and proto/locus.proto.

scene_pb2, locus_pb2 and locus_pb2_grpc are made by the build (protoc and
grpc_python_plugin, client/python/CMakeLists.txt) into
BUILD/python/locus/proto/, next to a copy of this file; they are not in the
source tree. Use the package from the build: PYTHONPATH=BUILD/python.
"""
