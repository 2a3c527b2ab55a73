// The status page meshmarkd serves at / (docs/api.md, Status page): one static HTML file whose
// script reads the JSON API with the operator's token. The page itself holds no data, so serving
// it needs no token; the token stays in the browser tab (sessionStorage, given once as
// /#token=...), and every request carries it as a bearer header, which a cross-site page cannot
// add (no CORS headers are served), so no other site can act with it.
#pragma once

namespace mm::service {

extern const char* const kStatusPageHtml;

}  // namespace mm::service
