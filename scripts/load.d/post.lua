-- wrk script: POSTs the JSON body in $GEOMINT_BODY to the URL's path, counts answers by class
-- (2xx, 503 with Retry-After, 503 without, anything else) and prints them with the exact
-- latency percentiles as one line of JSON when the run is done.
local body = os.getenv("GEOMINT_BODY")
local threads = {}

function setup(thread)
  table.insert(threads, thread)
end

function init(args)
  ok, busy, busy_bare, other = 0, 0, 0, 0
  if body and body ~= "" then
    wrk.method = "POST"
    wrk.body = body
    wrk.headers["Content-Type"] = "application/json"
  end
end

function response(status, headers, _)
  if status >= 200 and status < 300 then
    ok = ok + 1
  elseif status == 503 then
    if headers["Retry-After"] or headers["retry-after"] then busy = busy + 1 else busy_bare = busy_bare + 1 end
  else
    other = other + 1
  end
end

function done(summary, latency, _)
  local c = { ok = 0, busy = 0, busy_bare = 0, other = 0 }
  for _, t in ipairs(threads) do
    for k in pairs(c) do c[k] = c[k] + t:get(k) end
  end
  local e = summary.errors
  io.write(string.format(
    '{"requests":%d,"seconds":%.3f,"p50_ms":%.3f,"p99_ms":%.3f,"max_ms":%.3f,' ..
    '"ok":%d,"busy":%d,"busy_without_retry_after":%d,"other":%d,"socket_errors":%d}\n',
    summary.requests, summary.duration / 1e6, latency:percentile(50) / 1e3,
    latency:percentile(99) / 1e3, latency.max / 1e3, c.ok, c.busy, c.busy_bare, c.other,
    e.connect + e.read + e.write + e.timeout))
end
