"""FarmError: the one exception of the Locus Python client.

A failed call becomes a FarmError whose `code` is the gRPC status code and
whose message names the farm and, where the user can act, the fix, in the
words of the C++ client (FromGrpc in proto/wire/rpc.cpp). Problems found
before anything is sent (an unreadable token file, a scene file that does
not parse, plaintext to a remote address) are FarmErrors too, with the code
the coordinator would have used.
"""

import grpc


class FarmError(Exception):
    """A call to the farm, or the preparation of one, failed.

    Attributes:
        code: a grpc.StatusCode (code.name is e.g. "PERMISSION_DENIED").
        message: what went wrong, naming the farm and the fix.
        details: the server's own message (empty for local errors).
    """

    def __init__(self, code, message, details=""):
        super().__init__(message)
        self.code = code
        self.message = message
        self.details = details

    def __str__(self):
        return self.message

    def __repr__(self):
        return f"FarmError({self.code.name}, {self.message!r})"


def _looks_like_tls(details):
    # A TLS mismatch shows only as a failed connection; say where to look.
    return any(s in details for s in ("andshake", "SSL", "ssl", "Socket closed"))


def from_rpc_error(error, address):
    """The FarmError for a grpc.RpcError from a call to the farm at `address`."""
    code = error.code() if callable(getattr(error, "code", None)) else grpc.StatusCode.UNKNOWN
    details = (error.details() if callable(getattr(error, "details", None)) else "") or ""
    peer = f"farm at {address}"
    C = grpc.StatusCode
    if code in (C.INVALID_ARGUMENT, C.NOT_FOUND, C.ALREADY_EXISTS, C.FAILED_PRECONDITION,
                C.ABORTED):
        message = details
    elif code in (C.PERMISSION_DENIED, C.UNAUTHENTICATED):
        message = f"the {peer} refused the call ({code.name}): {details}"
    elif code == C.UNAVAILABLE:
        message = (f"cannot reach the {peer} ({details}); is it running, and is the address "
                   "right?")
        if _looks_like_tls(details):
            message += (" If the farm uses TLS, give ca= with the CA that signed its "
                        "certificate (and cert=/key= for mutual TLS).")
    elif code == C.DEADLINE_EXCEEDED:
        message = f"the {peer} did not answer in time"
    elif code == C.CANCELLED:
        message = f"call to the {peer} cancelled: {details}"
    else:
        message = f"{peer}: {details}"
    return FarmError(code, message, details)
