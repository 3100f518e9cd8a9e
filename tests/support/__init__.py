"""What tests and benchmarks share: clients of the server and helpers of several test files."""
