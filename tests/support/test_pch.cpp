// The object that builds the tests' precompiled header (support/test_pch.h).
