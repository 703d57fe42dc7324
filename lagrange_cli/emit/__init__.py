"""Backends: one emitter per output format, each `emit(model, form=..., **settings) -> str`."""

FORMS = ("lagrange", "matrix", "solved")
