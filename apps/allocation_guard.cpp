// The cairn command's global operator new and delete: malloc and free, except that one
// allocation above od::io::kMaxAllocationBytes fails at once with std::bad_alloc (or
// nullptr for the nothrow forms). MRPT sizes its vectors from the counts a rawlog stores
// before it reads the data, so a 2 kB corrupt rawlog claiming 4 billion points would
// otherwise zero-fill 16 GB before the read fails (found by fuzz/fuzz_rawlog.cpp); with the
// guard the reader's bad_alloc handler reports the entry as corrupt. Replacing the whole
// family (not only new) keeps every pair of allocation and release on malloc and free, which
// AddressSanitizer checks. Linked into `cairn` and the rawlog fuzzer, never into the
// libraries: a library does not replace its host's allocator.
#include <cstdlib>
#include <new>

#include "cairn/od/io/limits.hpp"

namespace {

void* Allocate(std::size_t size) noexcept {
  if (size > cairn::od::io::kMaxAllocationBytes) return nullptr;
  return std::malloc(size == 0 ? 1 : size);
}

void* AllocateAligned(std::size_t size, std::align_val_t align) noexcept {
  if (size > cairn::od::io::kMaxAllocationBytes) return nullptr;
  const std::size_t a = static_cast<std::size_t>(align);
  const std::size_t rounded = ((size == 0 ? 1 : size) + a - 1) / a * a;
  return std::aligned_alloc(a, rounded);
}

void* AllocateOrThrow(std::size_t size) {
  for (;;) {
    if (void* p = Allocate(size)) return p;
    std::new_handler handler = std::get_new_handler();
    if (handler == nullptr || size > cairn::od::io::kMaxAllocationBytes) throw std::bad_alloc();
    handler();
  }
}

void* AllocateAlignedOrThrow(std::size_t size, std::align_val_t align) {
  for (;;) {
    if (void* p = AllocateAligned(size, align)) return p;
    std::new_handler handler = std::get_new_handler();
    if (handler == nullptr || size > cairn::od::io::kMaxAllocationBytes) throw std::bad_alloc();
    handler();
  }
}

}  // namespace

void* operator new(std::size_t size) { return AllocateOrThrow(size); }
void* operator new[](std::size_t size) { return AllocateOrThrow(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept { return Allocate(size); }
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept { return Allocate(size); }
void* operator new(std::size_t size, std::align_val_t align) {
  return AllocateAlignedOrThrow(size, align);
}
void* operator new[](std::size_t size, std::align_val_t align) {
  return AllocateAlignedOrThrow(size, align);
}
void* operator new(std::size_t size, std::align_val_t align, const std::nothrow_t&) noexcept {
  return AllocateAligned(size, align);
}
void* operator new[](std::size_t size, std::align_val_t align, const std::nothrow_t&) noexcept {
  return AllocateAligned(size, align);
}

void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  std::free(p);
}
