"""Reference implementations the tests (and the developer benchmarks) compare mechsweep against;
not part of the installed package."""
