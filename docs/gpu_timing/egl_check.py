import ctypes
egl = ctypes.CDLL("libEGL.so.1")
egl.eglGetDisplay.restype = ctypes.c_void_p
egl.eglGetDisplay.argtypes = [ctypes.c_void_p]
egl.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int)]
egl.eglQueryString.restype = ctypes.c_char_p
egl.eglQueryString.argtypes = [ctypes.c_void_p, ctypes.c_int]
d = egl.eglGetDisplay(None)
a, b = ctypes.c_int(), ctypes.c_int()
ok = egl.eglInitialize(d, ctypes.byref(a), ctypes.byref(b))
print("EGL", ok, a.value, b.value, egl.eglQueryString(d, 0x3053), egl.eglQueryString(d, 0x3054), flush=True)
