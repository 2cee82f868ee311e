"""Formats: the files a user writes or keeps (design JSON, design-run configs, studies, sessions), typed with msgspec.

Decodes and checks them with one-line errors that name the key path, then builds core objects.
May import ``core.optimize``, ``core.analysis`` and ``core.kinematics``; never ``core.cli``.
"""
